"""Geometric and set errors found while compiling, each tied to a deck path."""


class CompileError(Exception):
    """problems: list of (deck path tuple, message)."""

    def __init__(self, problems: list[tuple[tuple, str]]):
        self.problems = problems
        super().__init__("; ".join(f"{'.'.join(map(str, p))}: {m}" for p, m in problems))
