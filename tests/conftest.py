"""Test-session hooks: the longest tests (marked ``long``) are collected first, so that with ``-n 2`` they start at
once on one worker while the other worker takes the many short ones (the suite then takes about half its summed time
instead of ending with one long test running alone)."""


def pytest_collection_modifyitems(config, items):
    items.sort(key=lambda item: item.get_closest_marker("long") is None)  # stable: order kept within each group
