"""`tail-beam` writing to a full device (`> /dev/full`, `--out /dev/full`): the output cannot be
written, which is said in one line naming where and why, with a non-zero exit; never a
traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

TAIL_BEAM = str(Path(sys.executable).parent / "tail-beam")
FULL = Path("/dev/full")


@pytest.mark.skipif(not FULL.exists(), reason="no /dev/full on this system")
def test_output_to_a_full_device_is_one_line_and_a_non_zero_exit(tmp_path):
    """identify, bag info, simulate into /dev/full and calibrate --out /dev/full: one line
    'cannot write ...: No space left on device', non-zero exit, no traceback."""
    from tail_beam_sim.cli import main

    bag = tmp_path / "bag"  # one impact: identify has a label to print
    assert main(["simulate", "--bag", str(bag)]) == 0  # in this process: only the bag is needed
    commands = {
        "identify": ([TAIL_BEAM, "identify", str(bag), "--no-calibrate"], "standard output"),
        "bag info": ([TAIL_BEAM, "bag", "info", str(bag)], "standard output"),
        "simulate": ([TAIL_BEAM, "simulate", "--window-s", "0.01"], "standard output"),
        "calibrate": ([TAIL_BEAM, "calibrate", str(bag), "--out", str(FULL)], str(FULL)),
    }
    for name, (command, where) in commands.items():
        with open(FULL, "w") as out:
            result = subprocess.run(
                command, stdout=out, stderr=subprocess.PIPE, text=True, timeout=120
            )
        assert result.returncode != 0, (name, result.stderr[-2000:])
        assert "Traceback" not in result.stderr, (name, result.stderr[-2000:])
        said = [line for line in result.stderr.splitlines() if "cannot write" in line]
        assert len(said) == 1, (name, result.stderr[-2000:])
        assert where in said[0] and "No space left on device" in said[0], (name, said)
