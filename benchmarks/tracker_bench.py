"""Multi-target tracker benchmark: floe's tracker (GNN, JPDA) beside Stone Soup's on the same
recorded detections.

    nice -n 10 python benchmarks/tracker_bench.py [--seed 0] [--duration-s 600] [--rounds 3]
        [--cases lawnmower,crossing,pd-0.6,clutter-5x] [--lost-sigma-m 300] [--q-per-s 0.1]
        [--frames benchmarks/tracker_bench_frames.json] [--json benchmarks/tracker_bench.json]

Every case flies the same fixed lawnmower (:data:`CASES`; detections floe's planner did not
produce): ``lawnmower`` (the world below), ``crossing`` (8 of the 12 icebergs in pairs that
pass within 50 m of each other), ``pd-0.6`` and ``clutter-5x`` (0.5 false alarms per frame);
both trackers are told the case's pd and clutter.

1. Recording (:mod:`benchmarks.tracker_bench_world`): a discovery-like world of 12 icebergs
   drifting in 3 km x 3 km, three UAVs flying lawnmower strips at 22 m/s with a 150 m
   footprint, a 2 Hz camera with pd 0.85, 0.1 false alarms per frame and r = 5 m^2 per axis,
   unlabelled. The frames (one per UAV per tick, with or without detections) and the truth
   are saved to ``--frames``; ``--load`` reads a recording instead of making one.
2. Every tracker gets the same scans in the same (t, vehicle) order, one scan per frame:
   floe's ``Tracker.scan`` with the frame's footprint, Stone Soup's ``update_tracker`` with
   the frame's detections (Stone Soup has no footprint: see "Mismatches" below).
3. Every second of mission time the confirmed tracks (extrapolated to the second from their
   last state) and the true icebergs in the area go to an
   :class:`observer.track_quality.TrackQualityRecorder` (GOSPA c = 150 m, p = 2, alpha = 2);
   true icebergs outside the area are passed as such (a track on one is not false). The
   measures and their one definition each, the same for every tracker
   (:mod:`observer.track_quality`): GOSPA mean; confirmed fraction at the end; time to
   confirm; false tracks per hour; ID switches; ``identity_errors`` (confirmed track ids
   assigned to more than one true iceberg over the run) and ``track_truth_changes`` (times
   a track is assigned to another iceberg than its last one); and, from each tracker's own
   record of what it associated, ``mixed_update_tracks``: confirmed track ids updated by
   detections of two or more true icebergs (clutter left out; a merge's updates go with the
   id it keeps; JPDA counts a detection whose association probability exceeds 0.5). It
   tells "a detection of another iceberg updated this track" (a wrong identity) from "a
   stale track's extrapolated mean passed near another iceberg" (which the matching-based
   ``identity_errors`` counts too).
4. Time per scan: the CPU time of this thread (``thread_time``) and the wall time
   (``perf_counter``) around the scan call only (inputs are built before), median and 90th
   percentile over all scans of a run; the trackers run interleaved, round
   by round, in a rotating order, so a busy host slows them alike; the figures are medians
   over the rounds. The measures of a run are deterministic: rounds after the first are
   checked to give the same measures.

Stone Soup configuration (facts from its documentation; our own wiring):
transition ``CombinedLinearGaussianTransitionModel([ConstantVelocity(q)] * 2)`` with
q = 0.1, measurement ``LinearGaussian(mapping=(0, 2), R = 5 I)``, Kalman predictor and
updater; one ``PDAHypothesiser`` (pd 0.85, gate 0.9999, clutter density 0.1 / (pi 150^2)
per m^2: likelihood ratios, like floe's association); GNN: it + ``GNNWith2DAssignment`` (the
likeliest joint assignment) in a ``MultiTargetTracker``; JPDA: it + ``JPDA`` in a
``MultiTargetMixtureTracker``. ``stonesoup-gnn-maha`` (not run by default): Stone Soup's
tutorial GNN, ``DistanceHypothesiser`` (Mahalanobis, missed distance
sqrt(-2 ln(1 - 0.9999)) = 4.29, the floe gate) + ``GNNWith2DAssignment``; it lets a track
with a large covariance take any clutter point (the distance ignores det S).
Initiation: ``MultiMeasurementInitiator`` (the same GNN inside, 3 updates to confirm, a
tentative track dropped after 1 s without an update, i.e. three missed 2 Hz frames: about
floe's 3 of 5), the new track's velocity variance 0.5 m^2/s^2 (floe's
``new_track_vel_var_m2_s2``). Deletion: ``CovarianceBasedDeleter`` on the
position variances at ``--lost-sigma-m`` squared, the trace at which floe's
``lost_sigma_m`` deletes (the same rule on both sides); both use ``--q-per-s``.

Mismatches (honest list): Stone Soup's ConstantVelocity is the continuous white-noise
acceleration model, ``Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]`` per axis; floe adds
``q dT`` to the velocity variance on a 0.1 s grid (the same intensity; position variance
grows alike to first order). Stone Soup's trackers know no sensor footprint: a track out of
view gets a missed-detection hypothesis every scan (harmless for its estimate, but no
"looked and not seen" deletion), so it deletes by covariance instead of by floe's existence
evidence, and it predicts every track at every scan of every UAV. Its PDA hypotheses have
no birth hypothesis, so a track with a large covariance takes a false alarm far from its
iceberg whenever ``pd N(z; z_hat, S) > lambda (1 - pd pg)``.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from tracker_bench_world import (
    Recording,
    WorldParams,
    load_recording,
    record,
    save_recording,
)

from observer.track_quality import TrackQualityRecorder

GATE_PROBABILITY = 0.9999
CONFIRM_HITS = 3
NEW_TRACK_VEL_VAR_M2_S2 = 0.5
Q_PER_S = 0.1


@dataclass
class RunResult:
    """One tracker over one recording: its measures and its per-scan times (s)."""

    measures: dict[str, Any]
    scan_s: list[float]
    scan_cpu_s: list[float]
    confirmed_ever: int


class _Adapter(Protocol):
    """A tracker behind one interface: ``scan(frame_index)`` (timed) and
    ``confirmed(t_s) -> {id: (x, y)}`` (not timed)."""

    def scan(self, k: int) -> None: ...

    def confirmed(self, t_s: float) -> dict[str, tuple[float, float]]: ...

    def update_sources(self) -> dict[str, set[str]]:
        """Per track id ever confirmed: the true icebergs whose detections updated it
        (clutter left out), from the tracker's own record of what it associated."""
        ...


class FloeAdapter:
    """floe's ``observer.Tracker`` (GNN or JPDA) with the frame's footprint."""

    def __init__(self, rec: Recording, association: str, lost_sigma_m: float | None = None,
                 q_per_s: float = Q_PER_S) -> None:
        from observer import Observer, ObserverConfig

        Footprint, ScanDetection, Tracker, TrackerConfig = floe_tracker_types()

        p = rec.params
        self.observer = Observer(ObserverConfig(q_per_s=q_per_s, r_m2=p.r_m2))
        self.tracker = Tracker(
            self.observer,
            TrackerConfig(
                association=association,
                pd=p.pd,
                clutter_per_frame=p.clutter_per_frame,
                confirm_hits=CONFIRM_HITS,
                new_track_vel_var_m2_s2=NEW_TRACK_VEL_VAR_M2_S2,
                gate_probability=GATE_PROBABILITY,
                lost_sigma_m=lost_sigma_m,
            ),
        )
        self.inputs = [
            (
                f.t_s,
                f.vehicle,
                Footprint(f.x_m, f.y_m, f.radius_m),
                [ScanDetection(x, y, p.r_m2) for x, y, _ in f.detections],
            )
            for f in rec.frames
        ]

        self.labels = [[label for _, _, label in f.detections] for f in rec.frames]
        self.sources: dict[str, set[str]] = {}
        self.ever_confirmed: set[str] = set()

    def scan(self, k: int) -> None:
        result = self.tracker.scan(*self.inputs[k])
        for i, tid in result.assigned.items():
            label = self.labels[k][i]
            if label is not None:
                self.sources.setdefault(tid, set()).add(label)
        for event in result.events:
            if event.kind == "confirmed":
                self.ever_confirmed.add(event.track_id)
            elif event.kind == "deleted" and event.reason.startswith("merged into "):
                # coalescence: the old id goes on with this track's updates
                into = event.reason.split()[2]
                self.sources.setdefault(into, set()).update(
                    self.sources.pop(event.track_id, set()))

    def update_sources(self) -> dict[str, set[str]]:
        return {tid: self.sources.get(tid, set()) for tid in self.ever_confirmed}

    def confirmed(self, t_s: float) -> dict[str, tuple[float, float]]:
        out: dict[str, tuple[float, float]] = {}
        for r in self.tracker.records():
            if r.status == "confirmed":
                s = self.observer.track(r.id)
                dt = t_s - s.t_s
                out[r.id] = (s.x_m + s.vx_m_s * dt, s.y_m + s.vy_m_s * dt)
        return out


class StoneSoupAdapter:
    """Stone Soup's GNN (MultiTargetTracker) or JPDA (MultiTargetMixtureTracker)."""

    def __init__(self, rec: Recording, association: str, delete_trace_m2: float,
                 q_per_s: float = Q_PER_S) -> None:
        import datetime

        import numpy as np
        from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
        from stonesoup.dataassociator.probability import JPDA
        from stonesoup.deleter.error import CovarianceBasedDeleter
        from stonesoup.deleter.time import UpdateTimeDeleter
        from stonesoup.hypothesiser.distance import DistanceHypothesiser
        from stonesoup.hypothesiser.probability import PDAHypothesiser
        from stonesoup.initiator.simple import MultiMeasurementInitiator
        from stonesoup.measures import Mahalanobis
        from stonesoup.models.measurement.linear import LinearGaussian
        from stonesoup.models.transition.linear import (
            CombinedLinearGaussianTransitionModel,
            ConstantVelocity,
        )
        from stonesoup.predictor.kalman import KalmanPredictor
        from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker
        from stonesoup.types.detection import Detection
        from stonesoup.types.state import GaussianState
        from stonesoup.updater.kalman import KalmanUpdater

        p = rec.params
        transition = CombinedLinearGaussianTransitionModel(
            [ConstantVelocity(q_per_s), ConstantVelocity(q_per_s)]
        )
        measurement = LinearGaussian(
            ndim_state=4, mapping=(0, 2), noise_covar=np.diag([p.r_m2, p.r_m2])
        )
        predictor = KalmanPredictor(transition)
        updater = KalmanUpdater(measurement)
        area_m2 = math.pi * p.footprint_radius_m**2
        pda = PDAHypothesiser(
            predictor,
            updater,
            clutter_spatial_density=p.clutter_per_frame / area_m2,
            prob_detect=p.pd,
            prob_gate=GATE_PROBABILITY,
        )
        if association == "gnn-mahalanobis":
            gate_m = math.sqrt(-2.0 * math.log(1.0 - GATE_PROBABILITY))
            gnn = GNNWith2DAssignment(
                DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=gate_m)
            )
        else:
            gnn = GNNWith2DAssignment(pda)
        v = NEW_TRACK_VEL_VAR_M2_S2
        initiator = MultiMeasurementInitiator(
            prior_state=GaussianState(np.zeros((4, 1)), np.diag([0.0, v, 0.0, v])),
            measurement_model=measurement,
            deleter=UpdateTimeDeleter(datetime.timedelta(seconds=1.0)),
            data_associator=gnn,
            updater=updater,
            min_points=CONFIRM_HITS,
        )
        deleter = CovarianceBasedDeleter(covar_trace_thresh=delete_trace_m2, mapping=[0, 2])
        if association != "jpda":
            self.tracker: Any = MultiTargetTracker(
                initiator=initiator,
                deleter=deleter,
                detector=None,
                data_associator=gnn,
                updater=updater,
            )
        else:
            jpda = JPDA(pda)
            self.tracker = MultiTargetMixtureTracker(
                initiator=initiator,
                deleter=deleter,
                detector=None,
                data_associator=jpda,
                updater=updater,
            )
        epoch = datetime.datetime(2026, 1, 1)
        self.inputs = []
        for f in rec.frames:
            stamp = epoch + datetime.timedelta(seconds=f.t_s)
            dets = {
                Detection(np.array([[x], [y]]), timestamp=stamp, measurement_model=measurement,
                          metadata={"truth": label})
                for x, y, label in f.detections
            }
            self.inputs.append((stamp, dets))
        self.epoch = epoch
        self.ids: dict[int, str] = {}
        self.seen: dict[str, Any] = {}

    def scan(self, k: int) -> None:
        self.tracker.update_tracker(*self.inputs[k])
        for track in self.tracker.tracks:  # every confirmed track, before a deleter drops it
            name = self.ids.setdefault(id(track), f"S{len(self.ids) + 1}")
            self.seen[name] = track

    def update_sources(self) -> dict[str, set[str]]:
        """Each track's updates: an ``Update`` state's hypothesis names the detection it
        took (GNN); JPDA's mixture update counts the detection whose hypothesis weighs more
        than 0.5 (floe's JPDA rule for ``assigned``)."""
        out: dict[str, set[str]] = {}
        for name, track in self.seen.items():
            labels: set[str] = set()
            for state in track.states:
                hypothesis = getattr(state, "hypothesis", None)
                if hypothesis is None:
                    continue
                mixture = getattr(hypothesis, "single_hypotheses", None)
                for h in mixture if mixture is not None else [hypothesis]:
                    if mixture is not None and float(getattr(h, "probability", 0.0)) <= 0.5:
                        continue
                    detection = getattr(h, "measurement", None)
                    label = getattr(detection, "metadata", {}).get("truth")
                    if label is not None:
                        labels.add(label)
            out[name] = labels
        return out

    def confirmed(self, t_s: float) -> dict[str, tuple[float, float]]:
        out: dict[str, tuple[float, float]] = {}
        for track in self.tracker.tracks:
            name = self.ids.setdefault(id(track), f"S{len(self.ids) + 1}")
            sv = track.state_vector
            dt = t_s - (track.timestamp - self.epoch).total_seconds()
            out[name] = (float(sv[0, 0] + sv[1, 0] * dt), float(sv[2, 0] + sv[3, 0] * dt))
        return out


def run(rec: Recording, make: Callable[[], _Adapter]) -> RunResult:
    """One tracker over the recording: scans timed, sampled every second."""
    adapter = make()
    quality = TrackQualityRecorder(c_m=150.0, p=2.0)
    area = rec.params
    times: list[float] = []
    cpu_times: list[float] = []
    ever: set[str] = set()
    frames = rec.frames
    next_sample_s = 0.0
    k = 0
    while next_sample_s <= rec.params.duration_s:
        while k < len(frames) and frames[k].t_s <= next_sample_s:
            f = frames[k]
            quality.frame(f.t_s, (f.x_m, f.y_m, f.radius_m), rec.truth_at(f.t_s))
            start_cpu, start = time.thread_time(), time.perf_counter()
            adapter.scan(k)
            times.append(time.perf_counter() - start)
            cpu_times.append(time.thread_time() - start_cpu)
            k += 1
        confirmed = adapter.confirmed(next_sample_s)
        ever.update(confirmed)
        everywhere = rec.truth_at(next_sample_s)
        truth = {
            tid: xy
            for tid, xy in everywhere.items()
            if area.x_min_m <= xy[0] <= area.x_max_m and area.y_min_m <= xy[1] <= area.y_max_m
        }
        outside = {tid: xy for tid, xy in everywhere.items() if tid not in truth}
        quality.sample(next_sample_s, confirmed, truth, outside)
        next_sample_s += 1.0
    measures = quality.to_dict(rec.params.duration_s)
    measures["track_truth_changes"] = quality.truth_changes
    measures["identity_errors"] = quality.identity_errors
    sources = adapter.update_sources()
    measures["mixed_update_tracks"] = sum(1 for labels in sources.values() if len(labels) > 1)
    return RunResult(measures, times, cpu_times, len(ever))


def percentile(values: Sequence[float], q: float) -> float:
    """Nearest-rank percentile (q in [0, 100])."""
    ordered = sorted(values)
    rank = max(1, math.ceil(q / 100.0 * len(ordered)))
    return ordered[rank - 1]


TRACKERS = ("floe-gnn", "floe-jpda", "stonesoup-gnn", "stonesoup-jpda", "stonesoup-gnn-maha")
DEFAULT_TRACKERS = TRACKERS[:4]
FLOE_TRACKER_NAMES = ("Footprint", "ScanDetection", "Tracker", "TrackerConfig")


def floe_tracker_types() -> tuple[Any, ...]:
    """floe's tracker classes, from ``observer`` (the agreed interface) or, failing that,
    from ``observer.tracker``."""
    import importlib

    found: list[Any] = []
    for name in FLOE_TRACKER_NAMES:
        for module in ("observer", "observer.tracker"):
            try:
                value = getattr(importlib.import_module(module), name, None)
            except ImportError:
                value = None
            if value is not None:
                found.append(value)
                break
        else:
            raise ImportError(f"observer.{name}")
    return tuple(found)


def floe_available() -> str | None:
    """None if floe's tracker can be imported, else why not."""
    try:
        floe_tracker_types()
    except ImportError as exc:
        return f"floe's tracker is not in this tree yet (no {exc})"
    return None


#: The benchmark's cases: overrides of :class:`WorldParams` on the chosen seed and duration.
#: All fly the fixed lawnmower (detections floe's planner did not produce).
CASES: dict[str, dict[str, Any]] = {
    "lawnmower": {},
    "crossing": {"crossing_pairs": 4},  # 8 of the 12 icebergs pass within 50 m in pairs
    "pd-0.6": {"pd": 0.6},
    "clutter-5x": {"clutter_per_frame": 0.5},
}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--duration-s", type=float, default=600.0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument(
        "--cases", default="lawnmower", help=f"comma list among {', '.join(CASES)}"
    )
    parser.add_argument("--frames", type=Path, default=Path("benchmarks/tracker_bench_frames.json"),
                        help="the lawnmower case's recording (written, or read with --load)")
    parser.add_argument("--load", action="store_true", help="read --frames instead of recording")
    parser.add_argument("--json", type=Path, default=Path("benchmarks/tracker_bench.json"))
    parser.add_argument(
        "--lost-sigma-m", type=float, default=300.0,
        help="both trackers delete a confirmed track once sqrt(trace P_xy) exceeds this (m): "
             "floe's lost_sigma_m, Stone Soup's CovarianceBasedDeleter at its square",
    )
    parser.add_argument("--q-per-s", type=float, default=Q_PER_S,
                        help="both trackers' constant-velocity process noise (m^2/s^3)")
    parser.add_argument(
        "--only", default=",".join(DEFAULT_TRACKERS), help="comma list of trackers to run"
    )
    args = parser.parse_args(argv)
    if args.rounds < 1 or not math.isfinite(args.duration_s) or args.duration_s <= 0:
        parser.error("--rounds must be >= 1 and --duration-s finite and > 0")
    wanted = [n for n in args.only.split(",") if n]
    unknown = [n for n in wanted if n not in TRACKERS]
    if unknown or not wanted:
        parser.error(f"--only: choose among {', '.join(TRACKERS)}")
    cases = [c for c in args.cases.split(",") if c]
    if not cases or any(c not in CASES for c in cases):
        parser.error(f"--cases: choose among {', '.join(CASES)}")
    if args.load and cases != ["lawnmower"]:
        parser.error("--load reads one recording: use it with --cases lawnmower")
    if not all(math.isfinite(v) and v > 0 for v in (args.lost_sigma_m, args.q_per_s)):
        parser.error("--lost-sigma-m and --q-per-s must be finite and > 0")
    missing_floe = floe_available()
    if missing_floe:
        print(missing_floe, "-- running Stone Soup only", file=sys.stderr)
        wanted = [n for n in wanted if not n.startswith("floe")]
        if not wanted:
            parser.error("nothing to run without floe's tracker")
    out: dict[str, Any] = {
        "rounds": args.rounds,
        "lost_sigma_m": args.lost_sigma_m,
        "q_per_s": args.q_per_s,
        "floe_missing": missing_floe,
        "cases": {},
    }
    for case in cases:
        if args.load:
            try:
                rec = load_recording(args.frames)
            except (OSError, ValueError, KeyError, TypeError) as exc:
                parser.error(f"--frames {args.frames}: not a recording ({exc})")
        else:
            rec = record(WorldParams(seed=args.seed, duration_s=args.duration_s, **CASES[case]))
            if case == "lawnmower":
                save_recording(rec, args.frames)
        print(f"case {case}")
        out["cases"][case] = run_case(rec, wanted, args.rounds, args.lost_sigma_m, args.q_per_s)
    args.json.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {args.json}")
    return 0


def run_case(rec: Recording, wanted: list[str], rounds: int, lost_sigma_m: float,
             q_per_s: float) -> dict[str, Any]:
    """Every wanted tracker over one recording, ``rounds`` interleaved rounds; prints the
    table and returns the recording's summary and each tracker's measures."""
    makers: dict[str, Callable[[], _Adapter]] = {
        "floe-gnn": lambda: FloeAdapter(rec, "gnn", lost_sigma_m, q_per_s),
        "floe-jpda": lambda: FloeAdapter(rec, "jpda", lost_sigma_m, q_per_s),
        "stonesoup-gnn": lambda: StoneSoupAdapter(rec, "gnn", lost_sigma_m**2, q_per_s),
        "stonesoup-jpda": lambda: StoneSoupAdapter(rec, "jpda", lost_sigma_m**2, q_per_s),
        "stonesoup-gnn-maha": lambda: StoneSoupAdapter(
            rec, "gnn-mahalanobis", lost_sigma_m**2, q_per_s
        ),
    }
    n_det = sum(len(f.detections) for f in rec.frames)
    n_clutter = sum(1 for f in rec.frames for d in f.detections if d[2] is None)
    print(
        f"recording: seed {rec.params.seed}, {rec.params.duration_s:.0f} s, "
        f"{len(rec.frames)} frames, {n_det} detections ({n_clutter} clutter), "
        f"{len(rec.truth)} icebergs"
    )
    results: dict[str, list[RunResult]] = {n: [] for n in wanted}
    for r in range(rounds):
        order = wanted[r % len(wanted) :] + wanted[: r % len(wanted)]
        for name in order:
            results[name].append(run(rec, makers[name]))
            last = results[name][-1]
            print(
                f"  round {r + 1} {name}: {sum(last.scan_cpu_s):.2f} s CPU, "
                f"{sum(last.scan_s):.2f} s wall in scans",
                flush=True,
            )
    summary: dict[str, Any] = {}
    for name, runs in results.items():
        first = runs[0]
        summary[name] = {
            **first.measures,
            "confirmed_tracks_ever": first.confirmed_ever,
            "deterministic_over_rounds": all(r.measures == first.measures for r in runs),
            "scan_cpu_ms_median": statistics.median(
                1e3 * statistics.median(r.scan_cpu_s) for r in runs
            ),
            "scan_cpu_ms_p90": statistics.median(1e3 * percentile(r.scan_cpu_s, 90) for r in runs),
            "scans_cpu_total_s": statistics.median(sum(r.scan_cpu_s) for r in runs),
            "scan_wall_ms_median": statistics.median(
                1e3 * statistics.median(r.scan_s) for r in runs
            ),
            "scan_wall_ms_p90": statistics.median(1e3 * percentile(r.scan_s, 90) for r in runs),
        }
    print_table(summary)
    return {
        "recording": {
            "seed": rec.params.seed,
            "duration_s": rec.params.duration_s,
            "frames": len(rec.frames),
            "detections": n_det,
            "clutter": n_clutter,
            "icebergs": len(rec.truth),
            "params": asdict(rec.params),
        },
        "trackers": summary,
    }


def print_table(summary: dict[str, dict[str, Any]]) -> None:
    """The trackers side by side."""

    def fmt(v: Any) -> str:
        if v is None:
            return "-"
        if isinstance(v, float):
            return f"{v:.3g}"
        return str(v)

    rows = [
        ("GOSPA mean (m)", lambda s: s["gospa_mean_m"]),
        ("confirmed fraction", lambda s: s["true_confirmed_fraction"]),
        ("time to confirm median (s)", lambda s: s["time_to_confirm_s"]["median"]),
        ("time to confirm max (s)", lambda s: s["time_to_confirm_s"]["max"]),
        ("false tracks / h", lambda s: s["false_tracks_per_hour"]),
        ("id switches", lambda s: s["id_switches"]),
        ("identity errors", lambda s: s.get("identity_errors")),
        ("track truth changes", lambda s: s.get("track_truth_changes")),
        ("tracks updated by 2+ icebergs", lambda s: s.get("mixed_update_tracks")),
        ("confirmed tracks ever", lambda s: s["confirmed_tracks_ever"]),
        ("scan CPU median (ms)", lambda s: s["scan_cpu_ms_median"]),
        ("scan CPU p90 (ms)", lambda s: s["scan_cpu_ms_p90"]),
        ("all scans CPU (s)", lambda s: s["scans_cpu_total_s"]),
        ("scan wall median (ms)", lambda s: s["scan_wall_ms_median"]),
        ("scan wall p90 (ms)", lambda s: s["scan_wall_ms_p90"]),
    ]
    names = list(summary)
    print(f"{'':28}" + "".join(f"{n:>16}" for n in names))
    for label, get in rows:
        print(f"{label:28}" + "".join(f"{fmt(get(summary[n])):>16}" for n in names))


if __name__ == "__main__":
    raise SystemExit(main())
