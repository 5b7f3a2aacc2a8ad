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
    proc = subprocess.Popen(
        [TAIL_BEAM, *verb], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    time.sleep(0.3)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err[-1500:]
    assert "Traceback" not in err and err.strip().endswith("interrupted"), err[-1500:]


def test_a_ctrl_c_that_an_extension_turns_into_an_import_error_is_still_130(tmp_path):
    """A Ctrl-C landing while a C extension initialises comes back as ``ImportError:
    initialization failed`` with the KeyboardInterrupt as its cause (pybind11, rclpy):
    reproduced here by a parser builder that takes
    the signal and raises so. Still 130 and one line."""
    script = tmp_path / "run.py"
    script.write_text(
        "import os, signal, sys, time\n"
        "import tail_beam_sim.cli as cli\n"
        "def broken(*args, **kwargs):\n"
        "    try:\n"
        "        os.kill(os.getpid(), signal.SIGINT)\n"
        "        time.sleep(5)\n"
        "    except KeyboardInterrupt as exc:\n"
        "        raise ImportError('initialization failed') from exc\n"
        "cli.build_parser = broken\n"
        "sys.exit(cli.main(['simulate']))\n"
    )
    result = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 130, result.stderr[-1500:]
    assert (
        "Traceback" not in result.stderr and result.stderr.strip() == "tail-beam: interrupted"
    ), result.stderr[-1500:]


def test_an_import_error_without_a_ctrl_c_is_not_called_an_interruption(tmp_path):
    """The same error with no signal behind it is a real failure: it is not hidden as 130."""
    script = tmp_path / "run.py"
    script.write_text(
        "import sys\n"
        "import tail_beam_sim.cli as cli\n"
        "def broken(*args, **kwargs):\n"
        "    raise ImportError('initialization failed')\n"
        "cli.build_parser = broken\n"
        "sys.exit(cli.main(['simulate']))\n"
    )
    result = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 1 and "ImportError: initialization failed" in result.stderr, (
        result.stderr[-1500:]
    )


def test_main_gives_the_callers_ctrl_c_handler_back(capsys):
    """main() takes SIGINT for its run (to tell an interruption from an extension's error) and
    gives it back: a program that calls it keeps its own handler."""
    from tail_beam_sim.cli import main

    def own(signum, frame):  # pragma: no cover - never called
        pass

    before = signal.signal(signal.SIGINT, own)
    try:
        assert main(["simulate", "--radius-m", "-1"]) == 2
        assert signal.getsignal(signal.SIGINT) is own
    finally:
        signal.signal(signal.SIGINT, before)
    assert "radius" in capsys.readouterr().err


def test_a_ctrl_c_python_can_only_report_is_delivered_again(capsys):
    """A KeyboardInterrupt raised where Python only reports it (a weakref callback, as the
    import machinery's module locks have) is neither printed nor lost while main()'s guard is
    installed: it comes back to the main thread as a KeyboardInterrupt."""
    import threading
    import weakref

    from tail_beam_sim.cli import _Interrupt

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers belong to the main thread")

    class Lock:
        pass

    def callback(_ref: object) -> None:
        raise KeyboardInterrupt

    previous = _Interrupt.install()
    try:
        lock = Lock()
        ref = weakref.ref(lock, callback)
        with pytest.raises(KeyboardInterrupt):
            del lock  # the callback's KeyboardInterrupt is unraisable here
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline:  # the re-delivered interrupt lands here
                pass
    finally:
        _Interrupt.restore(previous)
    assert ref() is None
    assert "Traceback" not in capsys.readouterr().err
