"""test/bench/make_docs.py: pages headed by command, commit and date; failures said as such."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
BENCH = """
import sys
from pathlib import Path

print("progress on stderr", file=sys.stderr)
print("  ... one step", file=sys.stderr)
print("| case | accuracy |")
print("| --- | --- |")
print("| fake | 97.5 % |")
print("after the table: 42 impacts")
out = Path(sys.argv[sys.argv.index("--out") + 1])
if "--fail" in sys.argv:
    sys.exit(3)
from PIL import Image
Image.new("RGB", (40, 30), (200, 30, 30)).save(out / "chart.png")
print(f"wrote {out / 'chart.png'}")
"""


@pytest.fixture(scope="module")
def make_docs():
    """The script, loaded as a module."""
    path = ROOT / "test" / "bench" / "make_docs.py"
    spec = importlib.util.spec_from_file_location("make_docs", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["make_docs"] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("make_docs", None)


def _family(make_docs, tmp_path: Path, extra: str = ""):
    script = tmp_path / "fake_bench.py"
    script.write_text(BENCH)
    command = f"python {script} --out {{out}}{extra}"
    return make_docs.Family(
        "fake", "Fake bench", "a fake benchmark", command, command + " --quick", 0.1,
        {"chart.png": "fake_chart.png"},
    )  # fmt: skip


def test_page_carries_the_command_commit_date_and_the_printed_table(make_docs, tmp_path):
    """A family that runs gets a page headed by its exact command and the checkout's commit,
    with its printed markdown table, its text, and the chart it wrote copied into docs/."""
    family = _family(make_docs, tmp_path)
    docs, work = tmp_path / "docs", tmp_path / "work"
    assert make_docs.generate([family], False, ROOT, work, docs) == 0
    text = (docs / "results" / "fake.md").read_text()
    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    assert f"## `python {tmp_path / 'fake_bench.py'} --out {work / 'fake'}`" in text
    assert f"Commit {head}" in text
    assert "UTC; sizing full;" in text
    assert "| fake | 97.5 % |" in text  # the table as markdown, not in a text block
    assert "```text\nafter the table: 42 impacts\n```" in text
    assert "wrote " not in text
    assert "Its log (stderr):\n\n```text\nprogress on stderr\n```" in text  # no '  ... '

    assert (docs / "fake_chart.png").read_bytes()[:4] == b"\x89PNG"
    assert "![fake_chart](../fake_chart.png)" in text
    index = (docs / "results" / "README.md").read_text()
    assert "| [fake](fake.md) | a fake benchmark | ok, full," in index
    assert "python test/bench/make_docs.py --quick" in index


def test_failing_benchmark_gives_a_page_that_says_so_and_no_old_results(make_docs, tmp_path):
    """A command that exits non-zero replaces the family's page with one saying FAILED and
    its exit status (no results header, no chart), the index says FAILED, and the run
    returns 1."""
    family = _family(make_docs, tmp_path, " --fail")
    docs, work = tmp_path / "docs", tmp_path / "work"
    (docs / "results").mkdir(parents=True)
    (docs / "results" / "fake.md").write_text("# Fake\n\nCommit abc1234; old results\n")
    assert make_docs.generate([family], False, ROOT, work, docs) == 1
    text = (docs / "results" / "fake.md").read_text()
    assert "**FAILED**" in text and "exited with status 3" in text
    assert "old results" not in text and "\nCommit " not in text
    assert "after the table: 42 impacts" in text  # the end of its output, to see why
    assert not (docs / "fake_chart.png").exists()
    assert (
        "| [fake](fake.md) | a fake benchmark | FAILED" in (docs / "results/README.md").read_text()
    )


def test_quick_sizing_runs_the_quick_command_and_says_so(make_docs, tmp_path):
    """--quick runs the family's quick command and the page names that sizing and the
    regenerate line carries --quick."""
    family = _family(make_docs, tmp_path)
    docs = tmp_path / "docs"
    assert make_docs.generate([family], True, ROOT, tmp_path / "work", docs) == 0
    text = (docs / "results" / "fake.md").read_text()
    assert "--out " in text and " --quick`" in text
    assert "sizing quick" in text
    assert "`python test/bench/make_docs.py --only fake --quick`" in text


def test_large_chart_is_stored_as_a_palette_png(make_docs, tmp_path, monkeypatch):
    """A chart over PNG_LIMIT_BYTES is stored with a 256-colour palette, one under it as is."""
    from PIL import Image

    source = tmp_path / "big.png"
    Image.linear_gradient("L").convert("RGB").save(source)
    monkeypatch.setattr(make_docs, "PNG_LIMIT_BYTES", 10)
    with Image.open(make_docs.store_chart(source, tmp_path / "out" / "small.png")) as image:
        assert image.mode == "P"
    monkeypatch.setattr(make_docs, "PNG_LIMIT_BYTES", 10**9)
    copied = make_docs.store_chart(source, tmp_path / "out" / "same.png")
    assert copied.read_bytes() == source.read_bytes()


def test_unknown_family_is_refused_by_name(make_docs, capsys):
    """--only with a family that does not exist is refused naming it and the known ones."""
    with pytest.raises(SystemExit):
        make_docs.main(["--only", "solvers,nosuch"])
    err = capsys.readouterr().err
    assert "nosuch" in err and "identification" in err


def test_commit_is_dirty_for_changed_code_but_not_for_its_own_pages(make_docs, tmp_path):
    """The commit header says dirty when a tracked file other than docs/results/*.md and
    docs/*.png differs from HEAD, and not for those, which the script itself rewrites."""
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(tmp_path)]
    (tmp_path / "docs" / "results").mkdir(parents=True)
    for name in ("code.py", "docs/results/solvers.md", "docs/chart.png"):
        (tmp_path / name).write_text("old\n")
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-q", "-m", "c"], check=True)
    clean = make_docs.commit(tmp_path)
    assert len(clean) >= 7 and "dirty" not in clean
    (tmp_path / "docs" / "results" / "solvers.md").write_text("new\n")
    (tmp_path / "docs" / "chart.png").write_text("new\n")
    assert make_docs.commit(tmp_path) == clean
    (tmp_path / "code.py").write_text("new\n")
    assert make_docs.commit(tmp_path) == f"{clean} dirty"


def test_index_links_pages_the_script_does_not_write(make_docs, tmp_path):
    """Other pages in docs/results/ (an archive kept by hand) are linked from the index as not
    written by the script."""
    family = _family(make_docs, tmp_path)
    docs = tmp_path / "docs"
    (docs / "results").mkdir(parents=True)
    (docs / "results" / "archive.md").write_text("# Archived figures\n")
    make_docs.generate([family], True, ROOT, tmp_path / "work", docs)
    index = (docs / "results" / "README.md").read_text()
    assert "Not written by this script: [archive.md](archive.md)" in index
    assert "[fake.md]" not in index.split("Not written by this script")[1]


def test_missing_command_and_missing_chart_are_reported(make_docs, tmp_path):
    """A command that cannot start gives a FAILED page (status 127) instead of stopping the
    run, and a chart a family promises but did not write is named on its page."""
    absent = make_docs.Family(
        "absent", "Absent", "a command that is not installed", "no-such-bench-xyz",
        "no-such-bench-xyz", 0.1,
    )  # fmt: skip
    family = _family(make_docs, tmp_path)
    family = make_docs.Family(**{**family.__dict__, "charts": {"other.png": "other_chart.png"}})
    docs = tmp_path / "docs"
    assert make_docs.generate([absent, family], False, ROOT, tmp_path / "work", docs) == 1
    failed = (docs / "results" / "absent.md").read_text()
    assert "**FAILED**" in failed and "exited with status 127" in failed
    fake = (docs / "results" / "fake.md").read_text()
    assert "Chart docs/other_chart.png was not written by this run." in fake
    assert not list((docs / "results").glob("*.partial"))
