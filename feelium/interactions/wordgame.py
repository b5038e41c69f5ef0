"""The finger-drawing guessing game's secret word: how it is chosen and how a guess is judged.

Choice: each round draws one entry of ``words`` with a ``random.Random``
seeded by ``(seed, round number)``, so a session is reproducible and rounds
differ; the skin shows it to the partner (who draws it), never the wearer's
view. Judging: the guess and every accepted spelling (``word|synonym|...``)
are folded to lower-case ASCII letters; a guess is right when it equals one of
them, also after dropping a plural ``s``/``es`` on either side.
"""

from __future__ import annotations

import random
import unicodedata


def _fold(text: str) -> str:
    ascii_text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    return "".join(ch for ch in ascii_text.lower() if ch.isalpha())


def _singulars(word: str) -> set[str]:
    forms = {word}
    if word.endswith("es") and len(word) > 3:
        forms.add(word[:-2])
    if word.endswith("s") and len(word) > 2:
        forms.add(word[:-1])
    return forms


def choose_word(words: tuple[str, ...], seed: int, round_number: int) -> str:
    """The round's entry (``word|synonym...``); raises ValueError on an empty list."""
    if not words:
        raise ValueError("interactions.words is empty; the drawing game needs at least one word")
    return random.Random(f"{seed}:{round_number}").choice(words)


def display_word(entry: str) -> str:
    """What the partner is asked to draw: the first spelling."""
    return entry.split("|")[0].strip()


def is_correct(guess: str, entry: str) -> bool:
    folded = _fold(guess)
    if not folded:
        return False
    guess_forms = _singulars(folded)
    for spelling in entry.split("|"):
        target = _fold(spelling)
        if target and (guess_forms & _singulars(target)):
            return True
    return False
