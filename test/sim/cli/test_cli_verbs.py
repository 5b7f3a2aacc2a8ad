"""``tail-beam VERB`` loads that verb alone: each verb's module imports what its work needs, and
loading every one of them cost each run a second or more."""

from __future__ import annotations

import subprocess
import sys

from tail_beam_sim.cli import build_parser


def _verbs(argv: list[str]) -> set[str]:
    parser = build_parser(argv)
    (sub,) = [a for a in parser._actions if a.dest == "command"]
    return set(sub.choices)


def test_a_named_verb_is_the_only_one_loaded():
    """The verb in first place is the one parser registered, options after it or not."""
    assert _verbs(["send", "--file", "x.yaml"]) == {"send"}
    assert _verbs(["caving", "--help"]) == {"caving"}


def test_help_and_an_unknown_verb_load_every_verb():
    """--help, no verb and an unknown one list every installed verb, as before."""
    everything = _verbs(["--help"])
    assert {"simulate", "send", "identify", "evaluate", "bag", "demo", "caving"} <= everything
    assert _verbs(["nosuch"]) == everything
    assert _verbs([]) == everything


def test_send_does_not_import_the_identifier_or_the_caving_study():
    """A verb's run imports no other verb's modules (here: send, against identify's models and
    caving's study)."""
    script = (
        "import sys\n"
        "from tail_beam_sim.cli import build_parser\n"
        "build_parser(['send', '--help'])\n"
        "print(sorted(m for m in sys.modules if m.startswith(('tail_beam_id.study', "
        "'tail_beam_id.methods'))))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60, check=True
    )
    assert result.stdout.strip() == "[]", result.stdout
