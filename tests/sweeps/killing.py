"""Killing a run the hard way: a private Ray temp dir per run, and SIGKILL for every process of that Ray instance."""

from __future__ import annotations

import os
import signal
import tempfile
from pathlib import Path


def private_ray_tmp() -> str:
    # Short: Ray's unix socket paths live under it and have a length limit.
    return tempfile.mkdtemp(prefix="rt", dir="/tmp")


def kill_ray_instance(ray_tmp: str) -> None:
    """SIGKILL every process of the Ray instance rooted at `ray_tmp` (and nothing else)."""
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
            env = Path(f"/proc/{pid}/environ").read_bytes()
        except OSError:
            continue
        if ray_tmp.encode() in cmd or f"RAY_TMPDIR={ray_tmp}".encode() in env:
            try:
                os.kill(int(pid), signal.SIGKILL)
            except ProcessLookupError:
                pass
