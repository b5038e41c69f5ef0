"""Who each touch id belonged to: the tally shared by the contact scorer (labels) and the scene bench (simulator).

Both match every event to the true contact it was nearest (or none) and then ask the same questions of
each id's list of owners: was any contact never touched (missed), touched by more than one id (split),
did an id move between contacts (swaps), did an id belong to no contact (phantom), and what kind did the
id end as against the kind of the contact it mostly belonged to.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any


def tally_owners(
    owners_by_id: Mapping[int, list[int]], final_kind: Mapping[int, str | None], truth_kinds: Sequence[str], kinds: Sequence[str]
) -> dict[str, Any]:
    """``owners_by_id``: id -> the index of the true contact of each of its events (-1: none);
    ``final_kind``: id -> the kind its ``up`` event said; ``truth_kinds``: each true contact's kind;
    ``kinds``: the kinds a contact may have (rows of the confusion, plus ``"none"`` as a column)."""
    ids_of: list[set[int]] = [set() for _ in truth_kinds]
    swaps = phantoms = 0
    confusion = {k: {c: 0 for c in (*kinds, "none")} for k in kinds}
    for eid, owners in owners_by_id.items():
        known = [o for o in owners if o >= 0]
        if not known:
            phantoms += 1
            continue
        swaps += sum(1 for a, b in zip(known, known[1:]) if a != b)
        for o in set(known):
            ids_of[o].add(eid)
        main = max(set(known), key=known.count)
        confusion[truth_kinds[main]][final_kind.get(eid) or "none"] += 1
    return {
        "touches": len(owners_by_id),
        "missed": sum(1 for ids in ids_of if not ids),
        "split": sum(max(len(ids) - 1, 0) for ids in ids_of),
        "swaps": swaps,
        "phantoms": phantoms,
        "confusion": confusion,
    }
