"""Helpers of the play tests: studies that need no training, the real `rllib-conv play` in a subprocess."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from rllib_conv.play.conditions import StudySettings, build_settings

ADMIN_TOKEN = "test-admin-token"
START_S = 60


def oracle_study(conditions: str = "agent,human", **options) -> StudySettings:
    """A bandit study whose agent condition plays the oracle agent (no training needed)."""
    agents = ["agent=oracle"] if "agent" in conditions.split(",") else []
    return build_settings(agents=agents, conditions=conditions, **options)


class StudyProcess:
    """`rllib-conv play ARGS` in a subprocess: the real command, to be stopped with Ctrl-C or killed."""

    def __init__(self, args: list[str]) -> None:
        cmd = [sys.executable, "-m", "rllib_conv.cli", "play", *args, "--admin-token", ADMIN_TOKEN]
        env = {**os.environ, "OMP_NUM_THREADS": "1"}
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
        self.lines: list[str] = []
        self.url = None
        deadline = time.monotonic() + START_S
        while self.url is None and time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if not line:
                break
            self.lines.append(line)
            if line.startswith("open http://127.0.0.1:"):
                self.url = line.split()[1]
        assert self.url, "the server did not start:\n" + "".join(self.lines)

    @property
    def port(self) -> int:
        return int(self.url.rstrip("/").rsplit(":", 1)[1])

    def kill(self) -> None:
        """SIGKILL: no shutdown code runs."""
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=20)

    def interrupt(self) -> int:
        """Ctrl-C; the exit status."""
        self.proc.send_signal(signal.SIGINT)
        return self.proc.wait(timeout=20)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self.proc.stdout.close()
