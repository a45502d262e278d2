"""Stand-ins for :func:`coons.validation.runner.run_case` used by the runner tests (importable by case processes)."""

from __future__ import annotations

import os
import signal
import time


def sleepy(case, options, stage=None):
    """Announce the coons stage, then hang."""
    if stage is not None:
        stage("coons")
    time.sleep(60)


def crashing(case, options, stage=None):
    """Announce the OCCT stage, then die as a segfaulting reference engine would."""
    if stage is not None:
        stage("occt")
    os.kill(os.getpid(), signal.SIGKILL)


def raising(case, options, stage=None):
    """Fail inside the harness itself."""
    raise RuntimeError("harness bug")
