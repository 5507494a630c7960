#!/usr/bin/env python3
"""Compares two `sinew` binaries on a noisy, shared machine: both at once (or in turn, on several threads).

    scripts/ab_bench.py OLD NEW [--rounds N] [--threads N] [--old-args A] [--new-args A] -- BENCH_ARGS...

e.g. `scripts/ab_bench.py /tmp/sinew_old target/release/sinew --rounds 3 --
assets/scenes/t7.ron --from 120 --frames 40 --runs 3`.

Each round runs `OLD bench BENCH_ARGS --threads 1` and `NEW bench ...` at the
same time, each pinned to a core of its own (`taskset`), swapping the cores
every round. The two then share whatever the machine is doing at that
moment (other tenants, the clock, the memory bandwidth), which one after the
other they do not: on the 2-core development machine, a build run against
itself this way reads within 0–5 % in a round, where runs one after the
other drift by 30 % and more within minutes. The ratio of each block
(NEW / OLD) is taken per round; one core can be steadily slower than the
other for a while, so two consecutive rounds (the cores swapped) make a
pair whose geometric mean cancels that. The table gives each side's median
ms/frame over the rounds, the median of the pairs' ratios (of the rounds'
with a single round) and each round's ratio.

`--old-args` and `--new-args` add arguments to one side only, so one
build can be compared with itself under another setting, e.g.
`--old-args="--bone-contact-interval 1"` (with `=`: the value starts with
dashes) and the same binary on both sides.

One thread each, so it compares single-thread work (what a change to a
kernel or a cache changes), not the scaling over threads. Standard library
only; needs `taskset` (util-linux) and two cores.

`--threads N` (N > 1) compares the scaling instead: each round runs the two
one after the other, unpinned, each on N threads, OLD first in odd rounds
and NEW first in even ones (a change to how work is shared out over the
threads shows only so). A round's ratio then holds whatever drift came
between its two runs, so take more rounds (8 or more).
"""
import argparse
import math
import os
import re
import statistics
import subprocess
import sys

# A block line of `sinew bench`: its name, then ms/frame first.
BLOCK = re.compile(r"^([a-z][a-z ]*[a-z])\s+(\d+\.\d+)(?:\s|$)")


def blocks(text):
    """The (name, ms/frame) of each block line, the wall included."""
    found = {}
    for line in text.splitlines():
        m = BLOCK.match(line)
        if m and m.group(1) not in found:
            found[m.group(1)] = float(m.group(2))
    return found


def main():
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        usage="%(prog)s OLD NEW [--rounds N] [--threads N] [--old-args A] [--new-args A] -- BENCH_ARGS...",
    )
    parser.add_argument("old", help="the sinew binary to compare against")
    parser.add_argument("new", help="the sinew binary under test")
    parser.add_argument(
        "--rounds", type=int, default=4, help="rounds, best even: pairs swap the cores, or which side runs first (default 4)"
    )
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="threads for each side; above 1 the sides run one after the other, unpinned (default 1)",
    )
    parser.add_argument(
        "--old-args", default="", help="more bench arguments for OLD only (one string, split on spaces)"
    )
    parser.add_argument(
        "--new-args", default="", help="more bench arguments for NEW only (one string, split on spaces)"
    )
    argv = sys.argv[1:]
    split = argv.index("--") if "--" in argv else len(argv)
    args = parser.parse_args(argv[:split])
    bench = argv[split + 1:]
    if not bench:
        parser.error("give sinew bench's arguments after --")
    extra = {"old": args.old_args.split(), "new": args.new_args.split()}
    if any(a == "--threads" or a.startswith("--threads=") for a in bench + extra["old"] + extra["new"]):
        parser.error("give the thread count as ab_bench's own --threads, before --")
    if args.rounds < 1:
        parser.error("--rounds must be at least 1")
    for binary in (args.old, args.new):
        if not os.access(binary, os.X_OK):
            sys.exit(f"{binary}: not an executable")
    if args.threads < 1:
        parser.error("--threads must be at least 1")
    pinned = args.threads == 1
    if pinned and (os.cpu_count() or 1) < 2:
        sys.exit("needs two cores: one for each side")

    sides = (("old", args.old), ("new", args.new))
    runs = {"old": [], "new": []}
    for r in range(args.rounds):
        cores = {"old": r % 2, "new": 1 - r % 2}

        def start(side, binary):
            command = [binary, "bench", *bench, *extra[side], "--threads", str(args.threads)]
            if pinned:
                command = ["taskset", "-c", str(cores[side]), *command]
            return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

        def collect(side, proc):
            out, _ = proc.communicate()
            if proc.returncode != 0:
                sys.exit(f"{side} ({getattr(args, side)}) failed in round {r + 1}:\n{out}")
            found = blocks(out)
            if not found:
                sys.exit(f"{side}: no block lines in its output:\n{out}")
            runs[side].append(found)

        if pinned:
            procs = {side: start(side, binary) for side, binary in sides}
            for side, proc in procs.items():
                collect(side, proc)
            how = f"old core {cores['old']}"
        else:
            order = sides if r % 2 == 0 else sides[::-1]
            for side, binary in order:
                collect(side, start(side, binary))
            how = f"{order[0][0]} first"
        wall = [runs[s][-1].get("wall", float("nan")) for s in ("old", "new")]
        print(f"round {r + 1}: wall {wall[0]:.2f} / {wall[1]:.2f} ms ({how})")

    names = [n for n in runs["old"][0] if all(n in run for run in runs["old"] + runs["new"])]
    print(f"\n{'block':<16}{'old ms':>10}{'new ms':>10}{'new/old':>10}   per round")
    for name in names:
        old = [run[name] for run in runs["old"]]
        new = [run[name] for run in runs["new"]]
        ratios = [n / o if o > 0 else float("nan") for o, n in zip(old, new)]
        pairs = [math.sqrt(a * b) for a, b in zip(ratios[::2], ratios[1::2])] or ratios
        each = " ".join(f"{x:.3f}" for x in ratios)
        print(
            f"{name:<16}{statistics.median(old):>10.3f}{statistics.median(new):>10.3f}"
            f"{statistics.median(pairs):>10.3f}   {each}"
        )


if __name__ == "__main__":
    main()
