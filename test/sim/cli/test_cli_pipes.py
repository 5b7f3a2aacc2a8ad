"""`tail-beam` piped into a reader that stops early (`| head -1`, a closed socket): the verb's
output has nowhere to go, which is the reader's choice, not an error of the tool. It must end
quietly, never with a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from bag_helpers import records, write_segments

TAIL_BEAM = str(Path(sys.executable).parent / "tail-beam")


def test_bag_info_into_a_closed_pipe_ends_without_a_traceback(tmp_path):
    """`tail-beam bag info BAG | head -0`: the pipe's reader is gone before the first line. No
    traceback on stderr and no exit status of a crash."""
    write_segments(tmp_path / "bag", [records(40)])
    process = subprocess.Popen(
        [TAIL_BEAM, "bag", "info", str(tmp_path / "bag")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    process.stdout.close()  # the reader leaves before the tool has written anything
    _, err = process.communicate(timeout=60)
    assert "Traceback" not in err.decode(), err.decode()[-2000:]
    assert process.returncode in (0, 141), process.returncode
