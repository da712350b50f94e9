"""Deck stage: YAML text -> frozen, validated ``Deck``. Imports neither numpy nor numba directly."""
