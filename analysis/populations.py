"""Independently trained populations of one kind pooled into one: the population as a level above the seed.

A plan's self-play entry with `populations: N` trains `<name>-p0` ... `<name>-p<N-1>`, and
the run's plan.json lists them under `population_groups` (kind -> member populations). The
report shows one result per kind: `pool` renames each member's rows to the kind in
`population` and keeps the member in `summaries.POPULATION_ID`, from which the statistics
average seeds within a population before the interval over populations. A folder whose
plan.json has no groups (every run of a one-population plan) is returned unchanged.
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping

import pandas as pd

from analysis.summaries import POPULATION_ID

GROUPS_KEY = "population_groups"  # plan.json's key: kind -> its independently trained populations


def member_kinds(plans: Iterable[Mapping[str, Any]]) -> dict[str, str]:
    """Member population -> its kind, over every game's plan.json (`read_plan`'s dicts); empty when none pools populations."""
    kinds: dict[str, str] = {}
    for plan in plans:
        for kind, members in plan.get(GROUPS_KEY, {}).items():
            kinds.update({member: kind for member in members})
    return kinds


def pool(frame: pd.DataFrame, kinds: Mapping[str, str]) -> pd.DataFrame:
    """`frame` with each member population's rows named by its kind in `population` and by itself in `POPULATION_ID`.

    Rows of populations that belong to no kind keep their name in both columns. With no
    `kinds`, or a frame without a `population` column, `frame` itself is returned.
    """
    if not kinds or "population" not in frame.columns:
        return frame
    out = frame.copy()
    out[POPULATION_ID] = out["population"]
    out["population"] = out["population"].map(lambda p: kinds.get(p, p))
    return out
