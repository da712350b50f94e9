"""Compile stage: a validated Deck -> a Problem of plain arrays, element groups and effects."""
