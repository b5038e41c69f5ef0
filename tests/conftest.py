"""Shared test settings: hypothesis is deterministic so CI never flakes on a new example."""

from hypothesis import settings

settings.register_profile("feelium", derandomize=True, deadline=None, max_examples=60)
settings.load_profile("feelium")
