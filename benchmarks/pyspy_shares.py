"""Inclusive and self shares of a py-spy raw profile, busy samples only.

    py-spy record -r 250 -f raw -o out.txt -- python benchmarks/sim_parts.py --runs 30
    python benchmarks/pyspy_shares.py out.txt [REGEX] [--top 60]

A function's inclusive share is the fraction of the busy samples (those not waiting in a
selector or an idle pool thread) whose stack holds it, counted once per sample; its self
share the fraction where it is the innermost frame. Line numbers are dropped, so a
function is one row. ``REGEX`` keeps only the matching rows of the inclusive list.
"""

from __future__ import annotations

import argparse
import collections
import re

_IDLE = ("_worker (concurrent/futures/thread.py", "EpollSelector.select",
         "_PollLikeSelector.select", "Condition.wait")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("profile", help="py-spy record -f raw output")
    parser.add_argument("pattern", nargs="?", default="")
    parser.add_argument("--top", type=int, default=60)
    args = parser.parse_args()
    inclusive: collections.Counter[str] = collections.Counter()
    own: collections.Counter[str] = collections.Counter()
    busy = 0
    with open(args.profile, encoding="utf-8") as handle:
        for line in handle:
            stack, _, count_text = line.rstrip().rpartition(" ")
            if not stack or not count_text.isdigit():
                continue
            count = int(count_text)
            frames = [re.sub(r":\d+\)", ")", f) for f in stack.split(";")]
            if frames[-1].startswith(_IDLE):
                continue
            busy += count
            for frame in set(frames):
                inclusive[frame] += count
            own[frames[-1]] += count
    if not busy:
        raise SystemExit(f"pyspy_shares: no busy samples in {args.profile}")
    print(f"{busy} busy samples; inclusive shares")
    shown = [(f, n) for f, n in inclusive.most_common() if re.search(args.pattern, f)]
    for frame, count in shown[:args.top]:
        print(f"{100 * count / busy:5.1f} % {frame[:120]}")
    print("self shares")
    for frame, count in own.most_common(min(args.top, 40)):
        print(f"{100 * count / busy:5.1f} % {frame[:120]}")


if __name__ == "__main__":
    main()
