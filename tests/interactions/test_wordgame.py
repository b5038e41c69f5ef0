"""How the drawing game's secret word is chosen and judged."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from feelium.interactions.wordgame import choose_word, display_word, is_correct

WORDS = ("heart", "cat|kitten|kitty", "boat|ship")


@pytest.mark.parametrize(
    "guess, entry, ok",
    [
        ("cat", "cat|kitten|kitty", True),
        ("  Kitty! ", "cat|kitten|kitty", True),
        ("cats", "cat|kitten|kitty", True),
        ("ship", "boat|ship", True),
        ("Hëart", "heart", True),
        ("hearth", "heart", False),
        ("dog", "cat|kitten|kitty", False),
        ("", "heart", False),
        ("!!", "heart", False),
    ],
)
def test_judging(guess, entry, ok):
    assert is_correct(guess, entry) is ok


@given(st.integers(0, 10_000), st.integers(1, 500))
def test_choice_is_reproducible_and_from_the_list(seed, round_number):
    word = choose_word(WORDS, seed, round_number)
    assert word in WORDS and word == choose_word(WORDS, seed, round_number)
    assert is_correct(display_word(word), word)


def test_rounds_vary():
    assert len({choose_word(WORDS, 7, n) for n in range(1, 30)}) == len(WORDS)


def test_empty_word_list_is_a_clear_error():
    with pytest.raises(ValueError, match="interactions.words"):
        choose_word((), 1, 1)
