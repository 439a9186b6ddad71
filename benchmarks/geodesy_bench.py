"""ENU -> geodetic per point: pymap3d's ``enu2geodetic`` against floe's scalar port
(``domain.geodesy.geodetic_from_enu``), interleaved in one process.

    python benchmarks/geodesy_bench.py [--rounds 7] [--points 2000]

Each round times ``--points`` conversions of random points within 50 km of Ny-Alesund
(78.9 N) with each, in turn (the order alternates), so a shared machine's load weighs on
both alike; prints the median and the minimum us per point of each, their ratio, and the
largest difference between the two over all points (deg, deg, m).
"""

from __future__ import annotations

import argparse
import random
import statistics
import time

import pymap3d

from domain.geodesy import geodetic_from_enu

ORIGIN = (78.93, 11.92, 0.0)


def _pymap3d(e: float, n: float, u: float) -> tuple[float, float, float]:
    lat, lon, alt = pymap3d.enu2geodetic(e, n, u, *ORIGIN)
    return float(lat), float(lon), float(alt)


def _floe(e: float, n: float, u: float) -> tuple[float, float, float]:
    return geodetic_from_enu(e, n, u, *ORIGIN)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--points", type=int, default=2000)
    args = parser.parse_args(argv)
    rng = random.Random(0)
    points = [(rng.uniform(-5e4, 5e4), rng.uniform(-5e4, 5e4), rng.uniform(0.0, 500.0))
              for _ in range(args.points)]
    times: dict[str, list[float]] = {"pymap3d": [], "floe": []}
    worst = [0.0, 0.0, 0.0]
    for r in range(args.rounds):
        order = [("pymap3d", _pymap3d), ("floe", _floe)]
        for name, fn in order if r % 2 == 0 else order[::-1]:
            t0 = time.process_time()
            for p in points:
                fn(*p)
            times[name].append(1e6 * (time.process_time() - t0) / len(points))
    for p in points:
        a, b = _floe(*p), _pymap3d(*p)
        worst = [max(w, abs(x - y)) for w, x, y in zip(worst, a, b, strict=True)]
    for name, got in times.items():
        print(f"{name:8s} median {statistics.median(got):8.1f} us/point, "
              f"min {min(got):8.1f}")
    ratio = statistics.median(times["pymap3d"]) / statistics.median(times["floe"])
    print(f"pymap3d / floe (medians): {ratio:.0f}x; largest difference: "
          f"{worst[0]:.1e} deg, {worst[1]:.1e} deg, {worst[2]:.1e} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
