"""Recording play sessions: files that only ever grow by whole, valid rows.

Layout of a recording folder (`rllib-conv play --out DIR`, default `play_sessions/`):

    DIR/bandit_human_agent.csv   one row per (pair, task, context, try): the user-study format
    DIR/bandit_human_human.csv   (pair,task,context,try,action_1,action_2), 1-based arms
    DIR/blocks/human_agent.csv   blocks: one row per move (BLOCKS_COLUMNS)
    DIR/blocks/human_human.csv
    DIR/sessions.jsonl           one JSON line per session: pair, game, mode, room, who sat where, run

Every `*.csv` directly in DIR is in the format of `analysis/data/user_study.csv` and passes
`rllib_conv.partners.user_study.load_user_study`, so DIR (or one of its files) can be
handed to `analysis` as recorded sessions as is. Pair numbers are unique within DIR
(the next pair is one past the largest pair seen in any of its files).

Appends are atomic: the new content (old bytes + the new rows) is written to a temporary
file in the same folder, fsync'ed, validated (for the bandit files: `load_user_study`
must accept it), and only then moved over the old file with `os.replace`. A crash, a
full disk or a row that would not validate leaves the file exactly as it was: never a
half row. One server process per folder (appends are serialised by a lock in-process).
"""

from __future__ import annotations

import csv
import io
import json
import os
import tempfile
import threading
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

from rllib_conv.common.user_study_table import COLUMNS as USER_STUDY_COLUMNS
from rllib_conv.common.user_study_table import load_user_study

BLOCKS_COLUMNS: tuple[str, ...] = ("pair", "task", "game", "move", "player", "action", "red_goal", "blue_goal", "score")
SESSIONS_FILE = "sessions.jsonl"
MODES: tuple[str, ...] = ("agent", "human")
# File stem per mode: "agent" mode is a person with the agent, "human" two people.
MODE_FILES = {"agent": "human_agent", "human": "human_human"}

Validator = Callable[[Path], None]


def _atomic_append(path: Path, data: bytes, header: bytes = b"", validate: Validator | None = None) -> None:
    """Append `data` to `path` (created with `header` if missing) by write-validate-replace.

    `validate(tmp_path)` sees the complete new file before it replaces the old one; if it
    raises, the old file is untouched and the exception propagates.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    old = path.read_bytes() if path.exists() else header
    if old and not old.endswith(b"\n"):
        # A file edited by hand may lack its last newline; never glue a new row onto an old one.
        old += b"\n"
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(old + data)
            f.flush()
            os.fsync(f.fileno())
        if validate is not None:
            validate(Path(tmp))
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


class CsvLog:
    """One CSV file with fixed `columns` that grows only by whole rows (see the module docstring).

    `validate(path)` checks a complete file (the existing one at construction, every
    candidate before it replaces the file); it raises ValueError on a bad file.
    """

    def __init__(self, path: str | Path, columns: Sequence[str], validate: Validator | None = None) -> None:
        self.path = Path(path)
        self.columns = tuple(columns)
        self.validate = validate
        self._lock = threading.Lock()
        if self.path.exists():
            self._check_existing()

    def _check_existing(self) -> None:
        with self.path.open(newline="") as f:
            header = next(csv.reader(f), None)
        if header is None:
            return  # an empty file: the header is written with the first rows
        if tuple(h.strip() for h in header) != self.columns:
            raise ValueError(f"recording file {str(self.path)!r} has columns {header}; expected {list(self.columns)} (use another --out folder)")
        if self.validate is not None:
            try:
                self.validate(self.path)
            except ValueError as exc:
                raise ValueError(f"recording file {str(self.path)!r} is not valid: {exc}") from None

    def _encode(self, rows: Iterable[Mapping[str, Any]]) -> bytes:
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        for row in rows:
            missing = [c for c in self.columns if c not in row]
            extra = sorted(set(row) - set(self.columns))
            if missing or extra:
                raise ValueError(f"{self.path.name}: a row must have exactly the columns {list(self.columns)}; missing {missing}, unexpected {extra}")
            writer.writerow([row[c] for c in self.columns])
        return buf.getvalue().encode()

    def append(self, rows: Sequence[Mapping[str, Any]]) -> None:
        """Append `rows` (dicts keyed by the columns) all at once, or nothing if anything fails."""
        data = self._encode(rows)  # a malformed row raises before the file is touched
        header = self._encode([dict(zip(self.columns, self.columns))])
        with self._lock:
            if self.path.exists() and self.path.stat().st_size == 0:
                self.path.unlink()  # an empty file gets its header like a missing one
            _atomic_append(self.path, data, header, self.validate)

    def read_column(self, column: str) -> list[str]:
        """The values of `column` in the file ([] if the file does not exist)."""
        if not self.path.exists():
            return []
        with self.path.open(newline="") as f:
            return [row[column] for row in csv.DictReader(f) if row.get(column) is not None]


def validate_user_study(path: Path) -> None:
    """Raise ValueError unless `path` is a valid user-study CSV (`load_user_study`)."""
    load_user_study(path)


def validate_blocks(path: Path) -> None:
    """Raise ValueError unless every row of a blocks recording has integer fields in range."""
    limits = {"pair": (1, None), "game": (1, None), "move": (1, 6), "player": (1, 2), "action": (0, 5), "red_goal": (0, 3), "blue_goal": (0, 3), "score": (0, 20)}
    with path.open(newline="") as f:
        for line, row in enumerate(csv.DictReader(f), start=2):
            if row.get("task") not in ("train", "test"):
                raise ValueError(f"line {line}: task must be 'train' or 'test', got {row.get('task')!r}")
            for column, (low, high) in limits.items():
                text = row.get(column)
                try:
                    value = int(text)
                except (TypeError, ValueError):
                    raise ValueError(f"line {line}: {column} must be an integer, got {text!r}") from None
                if value < low or (high is not None and value > high):
                    raise ValueError(f"line {line}: {column} must be in {low}..{high if high is not None else ''}, got {value}")


class SessionRecorder:
    """Every recording of one server: the per-game, per-mode logs, `sessions.jsonl`, the pair counter."""

    def __init__(self, out: str | Path) -> None:
        self.out = Path(out)
        if self.out.exists() and not self.out.is_dir():
            raise ValueError(f"--out {str(self.out)!r} is a file; expected a folder for the recordings")
        self.logs: dict[tuple[str, str], CsvLog] = {}
        for mode in MODES:
            stem = MODE_FILES[mode]
            self.logs[("bandit", mode)] = CsvLog(self.out / f"bandit_{stem}.csv", USER_STUDY_COLUMNS, validate_user_study)
            self.logs[("blocks", mode)] = CsvLog(self.out / "blocks" / f"{stem}.csv", BLOCKS_COLUMNS, validate_blocks)
        self.sessions_path = self.out / SESSIONS_FILE
        self._lock = threading.Lock()
        self._last_pair = max(self._known_pairs(), default=0)

    def _known_pairs(self) -> list[int]:
        pairs = [int(p) for log in self.logs.values() for p in log.read_column("pair") if p.strip().isdigit()]
        if self.sessions_path.exists():
            for n, line in enumerate(self.sessions_path.read_text().splitlines(), start=1):
                if not line.strip():
                    continue
                try:
                    pairs.append(int(json.loads(line)["pair"]))
                except (ValueError, KeyError, TypeError):
                    raise ValueError(f"{str(self.sessions_path)!r} line {n} is not a session record with a 'pair'; use another --out folder") from None
        return pairs

    def log(self, game: str, mode: str) -> CsvLog:
        """The log that `game` sessions in `mode` ("agent" or "human") append to."""
        try:
            return self.logs[(game, mode)]
        except KeyError:
            raise ValueError(f"no recording for game {game!r} and mode {mode!r}; games: bandit, blocks; modes: {list(MODES)}") from None

    def new_session(self, info: Mapping[str, Any]) -> int:
        """Reserve the next pair number, write the session's `info` line to sessions.jsonl; return the pair."""
        with self._lock:
            pair = self._last_pair + 1
            line = json.dumps({"pair": pair, **info}, sort_keys=False) + "\n"
            _atomic_append(self.sessions_path, line.encode())
            self._last_pair = pair
            return pair
