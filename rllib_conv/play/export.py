"""Exports of the study database: the user-study CSV the analysis reads, blocks moves, participants.

`rllib-conv play export DB` (and the admin page's downloads) write:

- bandit: one row per finished try in the format of `analysis/data/user_study.csv`
  (`pair,task,context,try,action_1,action_2`, 1-based arms; `pair` is the room number)
  plus a `condition` column, which `load_user_study` keeps. So
  `rllib-conv report ROOT --user-study exported.csv` analyses collected sessions as they
  are; `--condition NAME` exports one condition, to analyse conditions apart.
- blocks: one row per move of every finished game (`BLOCKS_COLUMNS` plus `condition`).
- participants (admin page): id, condition, pair, seat, state, why it ended, completion
  code, times: what a researcher matches against the recruitment platform.

A file is written to a temporary file beside it, checked (the bandit file must pass
`load_user_study`) and only then moved over the target: a failed export leaves the old
file as it was.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

from rllib_conv.common.atomic_files import replaced_atomically
from rllib_conv.common.user_study_table import COLUMNS as USER_STUDY_COLUMNS
from rllib_conv.common.user_study_table import load_user_study
from rllib_conv.play.store import Store, db_path

BLOCKS_COLUMNS: tuple[str, ...] = ("pair", "task", "game", "move", "player", "action", "red_goal", "blue_goal", "score")
EXPORT_COLUMNS = {"bandit": (*USER_STUDY_COLUMNS, "condition"), "blocks": (*BLOCKS_COLUMNS, "condition")}
PARTICIPANT_COLUMNS: tuple[str, ...] = (
    "id",
    "condition",
    "pair",
    "seat",
    "state",
    "end_reason",
    "completion_code",
    "created",
    "updated",
)


def _csv(columns: tuple[str, ...], rows: list[dict]) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, columns, lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    writer.writerows(rows)
    return buf.getvalue()


def study_game(store: Store) -> str:
    """The game of the study in `store` ("bandit" if it never recorded one)."""
    return store.settings().get("game", "bandit")


def table_csv(store: Store, condition: str | None = None) -> str:
    """The study's play records as CSV text: user-study rows (bandit) or blocks moves, of one condition or all."""
    game = study_game(store)
    if game == "bandit":
        rows = [dict(r) for r in store.tries(condition=condition)]
    else:
        task = "test" if store.settings().get("new_task") == "True" else "train"
        rows = [dict(r) | {"task": task} for r in store.moves(condition=condition) if r["score"] is not None]
    return _csv(EXPORT_COLUMNS[game], rows)


def participants_csv(store: Store) -> str:
    """Every participant as CSV text (PARTICIPANT_COLUMNS), in the order they arrived."""
    return _csv(PARTICIPANT_COLUMNS, [vars(p) for p in store.participants()])


def export(db: str | Path, out: str | Path | None = None, condition: str | None = None) -> tuple[Path, int]:
    """Write the play records of study database `db` (a file or its study folder) to `out`; return (path, rows).

    `out` defaults to `user_study.csv` (bandit) or `blocks.csv` beside the database.
    ValueError names the argument if `db` is not a study database, `condition` is not
    one of its conditions, or `out` is a folder.
    """
    path = db_path(db)
    store = Store(path, readonly=True)
    try:
        if condition is not None and condition not in store.condition_descriptions():
            raise ValueError(f"--condition {condition!r}: the study has the conditions {list(store.condition_descriptions())}")
        game = study_game(store)
        text = table_csv(store, condition)
    finally:
        store.close()
    target = Path(out) if out is not None else path.parent / ("user_study.csv" if game == "bandit" else "blocks.csv")
    if target.is_dir():
        raise ValueError(f"--out {str(target)!r} is a folder; expected the CSV file to write")
    target.parent.mkdir(parents=True, exist_ok=True)
    with replaced_atomically(target) as tmp:
        tmp.write_text(text, newline="")
        if game == "bandit":
            load_user_study(tmp)  # the analysis must read what we write
    return target, text.count("\n") - 1
