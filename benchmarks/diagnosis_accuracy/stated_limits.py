"""The detection limits the diagnosis states, per cause and base, and the plan drawn within them.

A detection limit (``shares.detection_limit``) is the smallest strength of a planted effect (rms over the
identification records, % of the output's peak-to-peak) above which the verdict is right in >= 95 % of the
single-cause cases. Here it is stated once, from the 28 balanced plans of seeds 35-62 (5600 cases, every row
diagnosed with session 41's code), with at least ``MIN_CASES`` cases at or above it; a cause and base with no
such strength in the drawn range has no limit: the diagnosis cannot be trusted to find that cause on such a
plant, at any strength drawn.

The ``within-limits`` plan (``accuracy.plan``) draws each vocabulary effect at or above its stated limit and
plants a cause only on a base where it has one; nulls and out-of-vocabulary effects are drawn as always. Its
accuracy is measured only on plans with seeds above ``CHOSEN_ON[-1]``: plans that took no part in stating the
limits. ``tests/test_stated_limits.py`` recomputes the table from those 28 plans' reports.
"""

from __future__ import annotations

from .planted import VOCABULARY

CHOSEN_ON = tuple(range(35, 63))  # the plan seeds the limits were stated from
MIN_CASES = 20  # single-cause cases at or above a stated limit, at least

# (cause, base): limit in % of p2p, or None (no strength in the drawn range has >= 95 % of >= MIN_CASES right)
LIMITS_PCT = {
    ("relaxation", "mrpim"): 1.0647013134632228,  # 301 of 308 right at or above; 308 cases
    ("relaxation", "virtual-dea"): None,  # 140 cases
    ("relaxation", "piezo"): 0.7333719073757233,  # 32 of 33; 140 cases
    ("delay", "mrpim"): 0.1981945475169865,  # 280 of 280; 280 cases
    ("delay", "virtual-dea"): 1.162435213534414,  # 84 of 88; 168 cases
    ("delay", "piezo"): 4.571999200785541,  # 51 of 53; 140 cases
    ("resonance", "mrpim"): 0.4565315196665961,  # 306 of 308; 308 cases
    ("resonance", "virtual-dea"): None,  # 140 cases (6.13 with 6 of 6 above: fewer than MIN_CASES)
    ("resonance", "piezo"): 2.631676183007996,  # 93 of 97; 140 cases
    ("creep", "mrpim"): 0.5674244020669907,  # 271 of 280; 280 cases
    ("creep", "virtual-dea"): None,  # 140 cases
    ("creep", "piezo"): 0.6107298226905497,  # 168 of 168; 168 cases
    ("interference", "mrpim"): 0.14327379790951258,  # 307 of 308; 308 cases
    ("interference", "virtual-dea"): 0.25205305077028844,  # 119 of 125; 140 cases
    ("interference", "piezo"): 0.16828246751804826,  # 133 of 140; 140 cases
    ("saturation", "mrpim"): 0.2828015083562644,  # 279 of 280; 280 cases
    ("saturation", "virtual-dea"): None,  # 168 cases
    ("saturation", "piezo"): 0.4364339876941183,  # 140 of 140; 140 cases
}


def stated_limit(cause: str, base: str) -> float | None:
    """The stated limit of a vocabulary cause on a base (None: none stated)."""
    return LIMITS_PCT.get((cause, base))


def in_scope(kinds, base: str) -> bool:
    """Whether every vocabulary effect of ``kinds`` has a stated limit on ``base`` (nulls and
    out-of-vocabulary effects always are)."""
    return all(stated_limit(k, base) is not None for k in kinds if k in VOCABULARY)


def minimum_strengths(kinds, base: str) -> dict[str, float]:
    """Per vocabulary effect of ``kinds``, the strength it is drawn at or above (its stated limit on ``base``)."""
    return {k: stated_limit(k, base) for k in kinds if k in VOCABULARY}


def out_of_scope() -> list[tuple[str, str]]:
    """(cause, base) pairs without a stated limit: not planted by the within-limits plan."""
    return [key for key, v in LIMITS_PCT.items() if v is None]
