"""Suggestions for misspelt names in error messages: one line that names the likely intent."""

from __future__ import annotations

import difflib


def closest(word: str, choices) -> str | None:
    """The choice most like ``word`` (difflib's ratio at least 0.6), or None."""
    close = difflib.get_close_matches(str(word), [str(c) for c in choices], n=1, cutoff=0.6)
    return close[0] if close else None


def did_you_mean(word: str, choices) -> str:
    """"; did you mean X?" for the choice most like ``word``, or "" where none is close."""
    best = closest(word, choices)
    return f"; did you mean {best}?" if best else ""
