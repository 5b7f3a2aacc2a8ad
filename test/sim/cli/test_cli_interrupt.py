"""Ctrl-C on `tail-beam` is exit status 130 and one line, whenever it comes: while the verbs'
modules (numpy, scipy, rosbags, the models) are still loading too."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

TAIL_BEAM = str(Path(sys.executable).parent / "tail-beam")


@pytest.mark.parametrize("verb", [["simulate"], ["evaluate", "--count", "2"], ["demo"]])
def test_a_ctrl_c_while_tail_beam_loads_is_130_and_one_line(verb):
    """0.3 s in, the verbs' modules are still importing (about a second here): the interrupt used
    to end in a KeyboardInterrupt traceback and status -2, outside main()'s guard."""
    proc = subprocess.Popen([TAIL_BEAM, *verb], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(0.3)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err[-1500:]
    assert "Traceback" not in err and err.strip().endswith("interrupted"), err[-1500:]
