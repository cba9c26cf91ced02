"""``python -m benchmarks``: the benchmarks of RESULTS.md and BENCHMARKS.md by name (from the repository root).

    python -m benchmarks list                 every benchmark: what it measures, its time, what it writes, its section
    python -m benchmarks show NAME            one benchmark in full (its usage, what it needs)
    python -m benchmarks run NAME [ARG ...]   run it; the arguments go to its script (``run NAME --help``: its usage)
"""
from __future__ import annotations

import os
import subprocess
import sys

from benchmarks.registry import BENCHMARKS, BY_NAME, ROOT, Benchmark

USAGE = __doc__.split("\n\n", 1)[1].rstrip()


def command(bench: Benchmark, args: list[str]) -> list[str]:
    runner = ["bash"] if bench.script.endswith(".sh") else [sys.executable]
    return [*runner, str(bench.path.relative_to(ROOT)), *args]


def show(bench: Benchmark) -> str:
    lines = [f"{bench.name}: {bench.measures}",
             f"  run:     python -m benchmarks run {bench.name} {bench.usage}".rstrip(),
             f"  time:    {bench.time} on the 2-core CPU",
             f"  writes:  {bench.writes}",
             f"  figures: {bench.cited}",
             f"  script:  benchmarks/{bench.script}" + (f" (then {', '.join(bench.steps)})" if bench.steps else "")]
    if bench.needs:
        lines.append(f"  needs:   {bench.needs}")
    return "\n".join(lines)


def table() -> str:
    w = max(len(b.name) for b in BENCHMARKS)
    t = max(len(b.time) for b in BENCHMARKS)
    rows = [f"{'name':<{w}}  {'time':<{t}}  what it measures  ->  where its figures are"]
    rows += [f"{b.name:<{w}}  {b.time:<{t}}  {b.measures}  ->  {b.cited}" for b in BENCHMARKS]
    return "\n".join(rows)


def fail(message: str) -> int:
    print(f"python -m benchmarks: {message}", file=sys.stderr)
    return 2


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(USAGE)
        return 0
    verb, rest = argv[0], argv[1:]
    if verb == "list":
        print(table())
        return 0
    if verb not in ("show", "run"):
        return fail(f"unknown command {verb!r} (list, show NAME, run NAME [ARG ...])")
    if not rest:
        return fail(f"{verb}: name a benchmark (python -m benchmarks list)")
    bench = BY_NAME.get(rest[0])
    if bench is None:
        return fail(f"no benchmark named {rest[0]!r}; the names: {', '.join(BY_NAME)}")
    if verb == "show":
        print(show(bench))
        return 0
    cmd = command(bench, rest[1:])
    print("$ " + " ".join(cmd), file=sys.stderr, flush=True)
    env = {**os.environ, "PYTHON": os.environ.get("PYTHON", sys.executable)}
    return subprocess.call(cmd, cwd=ROOT, env=env)


if __name__ == "__main__":
    sys.exit(main())
