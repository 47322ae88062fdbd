"""The words of a reproduction verdict, shared by the sweep's and the studies' reports: a claim of
a paper is reproduced, partly reproduced, not reproduced, inconclusive (the sample cannot reach
significance), incomplete (the sweep lacks runs), without the paper's value, without data, or
not reproducible here."""

from __future__ import annotations

from collections.abc import Iterable

REPRODUCED = "reproduced"
PARTLY = "partly"
NOT_REPRODUCED = "not reproduced"
INCONCLUSIVE = "inconclusive"
NO_DATA = "no data"
#: The verdict of a claim whose value the paper does not give (legibly): ours is shown alone.
NO_PAPER_VALUE = "no paper value"
NOT_REPRODUCIBLE = "not reproducible here"
#: A claim of a sweep that lacks runs: no verdict until every run is there.
INCOMPLETE = "incomplete"
#: Every verdict word, in the order summaries list them.
VERDICTS = (
    REPRODUCED,
    PARTLY,
    NOT_REPRODUCED,
    INCONCLUSIVE,
    INCOMPLETE,
    NO_PAPER_VALUE,
    NO_DATA,
    NOT_REPRODUCIBLE,
)


def inconclusive(n: int) -> str:
    """The verdict of a claim whose ``n`` units cannot reach significance."""
    return f"{INCONCLUSIVE} (n = {n})"


def verdict_word(verdict: str) -> str:
    """The verdict word a verdict starts with (``"inconclusive (n = 4)"`` → ``"inconclusive"``)."""
    return next((word for word in VERDICTS if verdict.startswith(word)), verdict)


def count_summary(verdicts: Iterable[str]) -> str:
    """``"19 reproduced, 7 partly, …"``: how many of ``verdicts`` carry each word (none left out
    but those of count 0)."""
    words = [verdict_word(v) for v in verdicts]
    return ", ".join(f"{words.count(w)} {w}" for w in VERDICTS if words.count(w))
