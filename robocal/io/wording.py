"""Counts in the words users read: "1 sample", "2 samples"."""


def plural(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"
