"""Regenerate docs/results/ (one page per benchmark family) and the charts docs/ shows.

    python test/bench/make_docs.py                      # every family, full sizing
    python test/bench/make_docs.py --quick              # every family, small sizing
    python test/bench/make_docs.py --only solvers,identification

Each family runs as a subprocess, the command a user would type, from the repository's root.
Its printed output becomes the page, headed by that command, the commit (``dirty`` when the
tree has changes), the date, the sizing and the wall time. Charts the command writes under
out/docs/<family>/ are copied into docs/. A family that fails gets a page saying so (with the
end of its output), never its previous results, and is listed at the end; the exit status is
then 1.
"""

from __future__ import annotations

import argparse
import datetime
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MARK = "<!-- make_docs:"  # a page's state for the index: "ok, quick, 1.5 min"
PNG_LIMIT_BYTES = 250_000  # a chart larger than this is stored with a 256-colour palette
# What make_docs writes itself, left out of "dirty".
GENERATED = (
    ":(exclude)docs/results/*.md",
    ":(exclude)docs/*.png",
)


@dataclass(frozen=True)
class Family:
    """One benchmark family: its page, its command at each sizing and the charts it writes.

    Commands are written as a user types them; ``{out}`` stands for the family's scratch
    folder (out/docs/<name>). ``charts`` maps a file the command writes there to its name in
    docs/.
    """

    name: str
    title: str
    summary: str
    full: str
    quick: str
    full_minutes: float
    charts: dict[str, str] = field(default_factory=dict)


FAMILIES: tuple[Family, ...] = (
    Family(
        "response",
        "One impact: what the sensors see",
        "a 25 mm coal sphere dropped 3.5 m onto the tail beam 1 m from the hinge: the tier "
        "chosen, rebound, peak force and pressure, and the sensors' traces charted",
        "tail-beam simulate --material coal --radius-m 0.025 --drop-height-m 3.5 "
        "--position-m 1.0 --plot {out}/response_coal.png",
        "tail-beam simulate --material coal --radius-m 0.025 --drop-height-m 3.5 "
        "--position-m 1.0 --plot {out}/response_coal.png",
        0.1,
        {"response_coal.png": "response_coal.png"},
    ),
    Family(
        "solvers",
        "Solvers: time and error against a converged reference",
        "every solver and setting timed on one impact (rigid beam), errors against Radau "
        "rtol 1e-11, speed as a ratio to Radau rtol 1e-8 in the same run; batch throughput",
        "tail-beam bench --full --no-tiers --out {out}",
        "tail-beam bench --no-tiers --out {out}",
        1.5,
        {"bench_solvers.png": "bench_solvers.png"},
    ),
    Family(
        "fidelity",
        "Fidelity: solvers on the modal beam and the tiers",
        "the solvers on the beam with its bending modes, and each tier (impulse, rigid, "
        "modal) against a modal Radau reference",
        "tail-beam bench --full --structure modal --batch-impacts 0 --out {out}",
        "tail-beam bench --structure modal --batch-impacts 0 --out {out}",
        2.0,
        {"bench_tiers.png": "bench_tiers.png", "bench_solvers.png": "bench_solvers_modal.png"},
    ),
    Family(
        "radius_series",
        "The study's radius series: an energy budget",
        "the restitution of coal spheres of 25-40 mm as simulated and as the study's finite "
        "element runs give it, the energy the difference asks the support to take, and the most "
        "each mechanism of the support can take (plate waves, panel flexure, crushing)",
        "python test/bench/bench_radius_series.py",
        "python test/bench/bench_radius_series.py",
        0.3,
    ),
    Family(
        "identification",
        "Identification: accuracy and latency of the methods",
        "every method on the nominal support's scene sets (paper, stream, mismatch) and on "
        "foreign supports (foreign, foreign_paper): accuracy with 95 % intervals, latency",
        "tail-beam evaluate --windows-ms 6,24 --out {out} --plot",
        "tail-beam evaluate --count 40 --noise 1 --windows-ms 6,24 --out {out} --plot",
        10.0,
        {
            "accuracy_vs_latency.png": "identification_accuracy_vs_latency.png",
            "accuracy_vs_size.png": "identification_accuracy_vs_size.png",
            "accuracy_vs_noise.png": "identification_accuracy_vs_noise.png",
            "reliability.png": "identification_reliability.png",
        },
    ),
    Family(
        "headline",
        "Headline: the statistical method on the shipped support",
        "the default method on the nominal support's paper, stream and mismatch sets at the "
        "shipped layout and without the accelerometer (README's headline table)",
        "tail-beam evaluate --sets paper,stream,mismatch --count 600 --noise 1 "
        "--rates shipped,nominal --methods statistical",
        "tail-beam evaluate --sets paper,stream,mismatch --count 100 --noise 1 "
        "--rates shipped,nominal --methods statistical",
        8.0,
    ),
    Family(
        "headline_foreign",
        "Headline: the statistical method on supports it never saw",
        "the default method on drawn foreign supports (stream and paper scenes) at the shipped "
        "layout, uncalibrated and self-calibrated from each support's own recording "
        "(README's headline table)",
        "tail-beam evaluate --sets foreign,foreign_paper --count 600 --noise 1 --rates shipped "
        "--methods statistical --profiles nominal,self-calibrated",
        "tail-beam evaluate --sets foreign,foreign_paper --count 100 --noise 1 --rates shipped "
        "--methods statistical --profiles nominal,self-calibrated",
        12.0,
    ),
    Family(
        "robustness",
        "Robustness: sensors that differ from the simulator's",
        "the foreign set's recordings changed as another sensor, DAQ or simulator would "
        "change them, identified self-calibrated; accuracy and confident wrong labels",
        "python test/bench/bench_robustness.py",
        "python test/bench/bench_robustness.py --supports 3",
        4.0,
    ),
    Family(
        "hysteresis",
        "Hysteresis: reading the contact's hysteresis on an unseen law",
        "the hysteresis network refitted with one contact law left out, scored on foreign "
        "supports of that law with and without it",
        "python test/bench/bench_hysteresis.py --varied 1000 --supports 10",
        "python test/bench/bench_hysteresis.py --varied 300 --supports 3",
        3.0,
    ),
    Family(
        "unseen_law",
        "Unseen contact law: what a law no training saw costs",
        "networks fitted with every law and with one law left out, scored on foreign "
        "supports of that law",
        "python test/bench/bench_unseen_law.py",
        "python test/bench/bench_unseen_law.py --varied 400 --stream 100 --supports 3",
        3.0,
    ),
    Family(
        "contact",
        "Contact duration: what reading it from the pulse buys",
        "networks retrained without the contact duration, with it read from the pulse (the "
        "half-sine or the force read-out), and with the true one",
        "python test/bench/bench_contact.py",
        "python test/bench/bench_contact.py --varied 400 --stream 150 --supports 3",
        3.0,
    ),
    Family(
        "contact_readout",
        "Contact read-out on supports unlike the shipped one",
        "read / true contact duration of the half-sine and of the force read-out over 25-100 mm "
        "particles on the nominal support and three with other mode spacings and masses; the "
        "read-outs' cost",
        "python test/bench/bench_contact_readout.py --count 100",
        "python test/bench/bench_contact_readout.py --count 40",
        2.0,
    ),
    Family(
        "oracle",
        "Oracle inputs: what the foreign supports' gap is made of",
        "networks retrained with inputs no sensor gives (impact position, IMU position)",
        "python test/bench/bench_oracle.py",
        "python test/bench/bench_oracle.py --varied 500 --stream 150 --supports 3",
        3.0,
    ),
    Family(
        "commissioning",
        "Commissioning: a few labelled impacts on a new support",
        "a logit offset (and scale) fitted to a support's first labelled impacts, scored on "
        "its others",
        "python test/bench/bench_commissioning.py --supports 30",
        "python test/bench/bench_commissioning.py --supports 5",
        1.5,
    ),
    Family(
        "vibration",
        "Vibration pipeline as deployed",
        "sim_node -> id_node -> bag_recorder as processes at the accelerometer's rates: "
        "real-time ratio, loss, CPU, bag size, live labels",
        "python test/bench/bench_vibration.py --rates 25600 51200 --duration 20",
        "python test/bench/bench_vibration.py --rates 25600 --duration 10",
        2.0,
    ),
    Family(
        "nodes",
        "Node suite over the middleware",
        "per-sample sensor rates sim_node -> id_node sustains in real time, label latency, "
        "recorder throughput",
        "python test/bench/bench_nodes.py",
        "python test/bench/bench_nodes.py --rates 2000 5000 --duration 4 --repeats 1",
        3.0,
    ),
    Family(
        "bag_segments",
        "The recorder's bag writer",
        "metadata.yaml rewritten at a segment close as the bag's file list grows, and the "
        "writer's CPU per recorded second of one support's traffic by segment length",
        "python test/bench/bench_bag_segments.py",
        "python test/bench/bench_bag_segments.py --repeats 3 --seconds 10",
        0.3,
    ),
    Family(
        "face_host",
        "Several supports in one process",
        "one face_host process with 1, 2 and 3 supports at the shipped layout in real time, and 3 "
        "supports over two processes (2 + 1): CPU s per simulated s per support, real-time ratio, "
        "samples lost",
        "python test/bench/bench_face_host.py --split 2+1 --record",
        "python test/bench/bench_face_host.py --split 2+1 --seconds 8",
        1.5,
    ),
    Family(
        "soak",
        "Soak: the nodes on a long stream",
        "sim_node, id_node and bag_recorder on a long generated stream: memory, counts, "
        "live labels against the bag's",
        "python test/bench/soak_nodes.py --impacts 1000",
        "python test/bench/soak_nodes.py --impacts 100",
        8.0,
    ),
)


@dataclass
class Outcome:
    """What one family's run gave."""

    family: Family
    command: str
    returncode: int
    stdout: str
    stderr: str
    seconds: float
    charts: list[Path] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)  # charts expected in docs/, not written

    @property
    def ok(self) -> bool:
        return self.returncode == 0


def commit(root: Path) -> str:
    """``git rev-parse --short HEAD`` of ``root``, plus `` dirty`` when its tree has changes
    other than the pages and charts this script writes."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", ".", *GENERATED],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    return f"{head} dirty" if status.strip() else head


def argv_of(command: str) -> list[str]:
    """The argv that runs ``command``: ``python`` is this interpreter, ``tail-beam`` the one
    installed beside it."""
    words = command.split()
    if words[0] == "python":
        words[0] = sys.executable
    else:
        beside = Path(sys.executable).parent / words[0]
        if beside.exists():
            words[0] = str(beside)
    return words


def run_family(family: Family, quick: bool, root: Path, work: Path, docs: Path) -> Outcome:
    """Run the family's command from ``root``, echoing its progress (stderr) as it comes, and
    copy the charts it wrote in ``work``/<name>/ into ``docs``."""
    out = work / family.name
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    shown = out.relative_to(root) if out.is_relative_to(root) else out
    command = (family.quick if quick else family.full).format(out=shown)
    print(f"[{family.name}] {command}", flush=True)
    started = time.monotonic()
    try:
        returncode, stdout, stderr = _run(argv_of(command), root, family.name)
    except OSError as error:  # the command itself is missing
        returncode, stdout, stderr = 127, "", f"{error}\n"
    seconds = time.monotonic() - started
    outcome = Outcome(family, command, returncode, stdout, stderr, seconds)
    if outcome.ok:
        for source, target in family.charts.items():
            if (out / source).exists():
                outcome.charts.append(store_chart(out / source, docs / target))
            else:
                outcome.missing.append(target)
    status = "ok" if outcome.ok else f"FAILED (exit {returncode})"
    print(f"[{family.name}] {status} in {seconds:.0f} s", flush=True)
    return outcome


def _run(argv: list[str], root: Path, name: str) -> tuple[int, str, str]:
    """Run ``argv`` from ``root``: its exit status, stdout and stderr, stderr echoed as it
    comes (the benchmarks' progress)."""
    with subprocess.Popen(
        argv, cwd=root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, errors="replace"
    ) as process:
        printed: list[str] = []
        reader = threading.Thread(target=lambda: printed.append(process.stdout.read()))
        reader.start()
        progress = []
        for line in process.stderr:
            progress.append(line)
            print(f"[{name}]   {line.rstrip()}", flush=True)
        reader.join()
        returncode = process.wait()
    return returncode, "".join(printed), "".join(progress)


def store_chart(source: Path, target: Path) -> Path:
    """Copy a PNG chart, as a 256-colour palette image when it is over PNG_LIMIT_BYTES."""
    target.parent.mkdir(parents=True, exist_ok=True)
    if source.stat().st_size <= PNG_LIMIT_BYTES:
        shutil.copyfile(source, target)
        return target
    from PIL import Image

    with Image.open(source) as image:
        image.convert("RGB").quantize(colors=256).save(target, optimize=True)
    return target


def _blocks(text: str) -> str:
    """Printed output as markdown: runs of lines starting with '|' (tables the benchmark prints
    as markdown) as they are, everything else in text blocks; 'wrote <file>' lines dropped."""
    lines = [line.rstrip() for line in text.splitlines() if not line.startswith("wrote ")]
    parts: list[str] = []
    run: list[str] = []
    table = False
    for line in [*lines, None]:
        is_table = line is not None and line.lstrip().startswith("|")
        if line is None or (is_table != table and run):
            body = "\n".join(run).strip("\n")
            if body:
                parts.append(body if table else f"```text\n{body}\n```")
            run = []
        if line is not None:
            run.append(line.strip() if is_table else line)
            table = is_table
    return "\n\n".join(parts)


def _log(stderr: str, limit: int = 40) -> list[str]:
    """The context a benchmark prints on stderr (sizes, seeds, times), as a text block under a
    heading (nothing when there is none); progress ('  ... '), 'wrote <file>' and ROS [INFO]
    lines left out."""
    skip = ("  ... ", "wrote ", "[INFO]")
    lines = [x.rstrip() for x in stderr.splitlines() if x.strip() and not x.startswith(skip)]
    if not lines:
        return []
    cut = [f"... ({len(lines) - limit} more lines)"] if len(lines) > limit else []
    return ["Its log (stderr):", "", "```text", *lines[:limit], *cut, "```", ""]


def _state(outcome: Outcome, quick: bool) -> str:
    """'ok' or 'FAILED', the sizing and the minutes taken."""
    ok = "ok" if outcome.ok else "FAILED"
    return f"{ok}, {'quick' if quick else 'full'}, {outcome.seconds / 60:.1f} min"


def page(outcome: Outcome, revision: str, date: str, quick: bool, docs: Path) -> str:
    """The markdown page of one family's run (a failure page when it failed)."""
    family = outcome.family
    sizing = "quick (`--quick`, small sizes, wide intervals)" if quick else "full"
    head = [
        f"{MARK} {_state(outcome, quick)} -->",
        f"# {family.title}",
        "",
        f"{family.summary[0].upper()}{family.summary[1:]}.",
        "",
        f"Regenerate: `python test/bench/make_docs.py --only {family.name}"
        + (" --quick" if quick else "")
        + "`.",
        "",
        f"## `{outcome.command}`",
        "",
    ]
    if not outcome.ok:
        tail = "\n".join((outcome.stdout + "\n" + outcome.stderr).strip().splitlines()[-30:])
        return "\n".join(
            head
            + [
                f"**FAILED**: this page holds no current results. The command exited with status "
                f"{outcome.returncode} after {outcome.seconds:.0f} s, at commit {revision}, "
                f"on {date}.",
                "",
                "Charts of this family in docs/ were not rewritten by this run.",
                "",
                "The end of its output:",
                "",
                f"```text\n{tail}\n```",
                "",
            ]
        )
    charts = [f"![{path.stem}](../{path.relative_to(docs).as_posix()})" for path in outcome.charts]
    charts += [f"Chart docs/{name} was not written by this run." for name in outcome.missing]
    return "\n".join(
        head
        + [
            f"Commit {revision}, {date}; sizing {sizing}; took {outcome.seconds:.0f} s "
            "(2-core machine, shared: compare speeds as the ratios within one run).",
            "",
            _blocks(outcome.stdout),
            "",
        ]
        + _log(outcome.stderr)
        + ([*charts, ""] if charts else [])
    )


def index(outcomes: Sequence[Outcome], results: Path, quick: bool) -> str:
    """docs/results/README.md: one line per page, how to regenerate, and how long it takes."""
    ran = {o.family.name: o for o in outcomes}
    total = sum(f.full_minutes for f in FAMILIES)
    lines = [
        "# Results",
        "",
        "Every page here is written by one command; none is edited by hand. Each page is "
        "headed by the command that produced its table, the commit and the date.",
        "",
        "```",
        "python test/bench/make_docs.py                  # every family, full sizing",
        "python test/bench/make_docs.py --quick          # every family, small sizing",
        "python test/bench/make_docs.py --only FAMILY    # one family (comma-separated for more)",
        "```",
        "",
        f"The full run takes about {total:.0f} minutes on a 2-core machine (an estimate from each "
        "family's sizing; the last column gives the time each page's run took), `--quick` about "
        "15 minutes; the node families need ROS 2. It also rewrites the charts in docs/.",
        "",
        "| page | what it measures | last run |",
        "| --- | --- | --- |",
    ]
    listed = [*FAMILIES, *(o.family for o in outcomes if o.family not in FAMILIES)]
    for family in listed:
        path = results / f"{family.name}.md"
        state = _state(ran[family.name], quick) if family.name in ran else _state_of(path)
        lines.append(f"| [{family.name}]({family.name}.md) | {family.summary} | {state} |")
    others = sorted(
        p.name for p in results.glob("*.md") if p.stem not in {"README", *(f.name for f in listed)}
    )
    if others:
        lines += ["", "Not written by this script: " + ", ".join(f"[{n}]({n})" for n in others)]
    return "\n".join(lines) + "\n"


def _state_of(path: Path) -> str:
    """The state of a page this run left alone, from the mark its run left in it."""
    if not path.exists():
        return "not generated"
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith(MARK):
            return line.removeprefix(MARK).removesuffix(" -->").strip()
    return "unknown"


def _write(path: Path, text: str) -> None:
    """Write a page whole or not at all (through a temporary file and a rename)."""
    partial = path.with_suffix(".md.partial")
    partial.write_text(text, encoding="utf-8")
    partial.replace(path)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--only",
        default="",
        help=f"families, comma-separated, of: {', '.join(f.name for f in FAMILIES)}",
    )
    parser.add_argument("--quick", action="store_true", help="small sizing (a few minutes)")
    parser.add_argument("--docs", type=Path, default=ROOT / "docs", help="docs folder")
    parser.add_argument(
        "--work", type=Path, default=ROOT / "out" / "docs", help="scratch folder of the runs"
    )
    args = parser.parse_args(argv)
    names = [n for n in args.only.split(",") if n]
    known = {f.name: f for f in FAMILIES}
    unknown = [n for n in names if n not in known]
    if unknown:
        parser.error(f"unknown family {', '.join(unknown)}; known: {', '.join(known)}")
    chosen = [known[n] for n in names] if names else list(FAMILIES)
    return generate(chosen, args.quick, ROOT, args.work.resolve(), args.docs.resolve())


def generate(families: Sequence[Family], quick: bool, root: Path, work: Path, docs: Path) -> int:
    """Run ``families`` and write their pages and docs/results/README.md; 1 if any failed."""
    results = docs / "results"
    results.mkdir(parents=True, exist_ok=True)
    revision = commit(root)
    outcomes = []
    for number, family in enumerate(families, 1):
        print(f"({number}/{len(families)})", end=" ", flush=True)
        date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        outcome = run_family(family, quick, root, work, docs)
        _write(results / f"{family.name}.md", page(outcome, revision, date, quick, docs))
        outcomes.append(outcome)
    _write(results / "README.md", index(outcomes, results, quick))
    failed = [o for o in outcomes if not o.ok]
    print(f"wrote {len(outcomes)} pages and {sum(len(o.charts) for o in outcomes)} charts")
    for o in failed:
        print(f"FAILED: {o.family.name} (exit {o.returncode}): {o.command}")
    for o in outcomes:
        for name in o.missing:
            print(f"MISSING CHART: {o.family.name} did not write docs/{name}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
