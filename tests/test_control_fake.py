"""A fake :class:`DaemonControl` (moving vehicles, drifting targets, a journal) and a helper
that serves it with a real :class:`ControlServer` from a background thread; shared by the
control API, CLI and live-page tests. The tests at the bottom check the fake itself."""

from __future__ import annotations

import asyncio
import math
import threading
import time
from collections.abc import AsyncIterator
from typing import Any

from groundstation.daemon.control.contract import VEHICLE_ACTIONS, DaemonControl
from groundstation.daemon.control.server import ControlServer

SPEED_M_S = 22.0
LOITER_RADIUS_M = 80.0
FOV_M = 150.0
TRACK_POINTS = 60


class FakeControl:
    """Three vehicles flying to their targets and circling them; targets drifting at their
    velocity, ``sigma`` growing 1/s and reset when a vehicle is within FOV; journal events
    pushed to every subscriber. ``advance(dt_s)`` moves the world; ``calls`` records writes;
    ``refuse`` (a reason) makes every write refused.

    The tracker's side, as the daemon reports it: ``tracks`` (A confirmed, B a prior entry,
    C tentative, and a tentative ``N7`` with no target entry), ``track_counts`` and a 3 x 3
    grid of 500 m ``search_cells`` whose values grow with time (the last cell most)."""

    def __init__(self, n_vehicles: int = 3) -> None:
        self.t = 0.0
        self.calls: list[tuple[Any, ...]] = []
        self.refuse: str | None = None
        self._subscribers: list[asyncio.Queue[dict[str, Any] | None]] = []
        self._events: list[dict[str, Any]] = [{"t": 0.0, "event": "start"}]
        self._next_id = 1
        self.targets: dict[str, dict[str, Any]] = {}
        for tid, x, y, vx, vy in (("A", 600.0, 300.0, 0.5, -0.3), ("B", -400.0, 500.0, 0.0, 1.0),
                                  ("C", 200.0, -600.0, -1.0, 0.2)):
            self._new_target(tid, x, y, vx, vy, 10.0)
        self.statuses = {"A": "confirmed", "B": "prior", "C": "tentative"}
        self.vehicles: list[dict[str, Any]] = []
        names = list(self.targets)
        for i in range(n_vehicles):
            heading = 2.0 * math.pi * i / max(1, n_vehicles)
            self.vehicles.append({
                "id": f"uav{i + 1}", "name": f"X8-{i + 1}", "system_id": i + 1,
                "x_m": 0.0, "y_m": 0.0, "alt_m": 100.0 + 10 * i, "heading_rad": heading,
                "speed_m_s": SPEED_M_S, "mode": "AUTO", "armed": True, "status": "active",
                "launch_held": None, "link": "ok", "battery_pct": 95.0 - 5 * i,
                "target": names[i % len(names)], "route": names[i % len(names):][:2],
                "aim": None, "track": [[0.0, 0.0]]})

    # -------------------------------------------------------------- world

    def _new_target(self, tid: str, x: float, y: float, vx: float, vy: float,
                    sigma0: float) -> dict[str, Any]:
        target = {"id": tid, "x_m": x, "y_m": y, "vx_m_s": vx, "vy_m_s": vy, "sigma": sigma0,
                  "cov_xy": [sigma0 * 0.6, sigma0 * 0.1, sigma0 * 0.4], "lost": False,
                  "last_seen_s": None}
        self.targets[tid] = target
        return target

    def emit(self, event: str, **fields: Any) -> None:
        line = {"t": round(self.t, 3), "event": event, **fields}
        self._events = [*self._events[-49:], line]
        for q in self._subscribers:
            q.put_nowait(line)

    def close(self) -> None:
        """End every subscription (the daemon stops)."""
        for q in self._subscribers:
            q.put_nowait(None)

    def advance(self, dt_s: float) -> None:
        self.t += dt_s
        for target in self.targets.values():
            target["x_m"] += target["vx_m_s"] * dt_s
            target["y_m"] += target["vy_m_s"] * dt_s
            target["sigma"] += dt_s
        for v in self.vehicles:
            if v["status"] != "active":
                continue
            goal = self.targets.get(v["target"] or "")
            if goal is None:
                continue
            gx, gy = goal["x_m"], goal["y_m"]
            v["aim"] = [gx, gy]
            dx, dy = gx - v["x_m"], gy - v["y_m"]
            dist = math.hypot(dx, dy)
            if dist > LOITER_RADIUS_M * 1.2:
                v["heading_rad"] = math.atan2(dy, dx)
            else:  # circle the target: fly the tangent, leaning slightly inwards
                v["heading_rad"] = math.atan2(dy, dx) - math.pi / 2 + 0.3
            v["x_m"] += SPEED_M_S * dt_s * math.cos(v["heading_rad"])
            v["y_m"] += SPEED_M_S * dt_s * math.sin(v["heading_rad"])
            v["track"] = [*v["track"][-(TRACK_POINTS - 1):],
                          [round(v["x_m"], 1), round(v["y_m"], 1)]]
            for target in self.targets.values():
                if math.hypot(target["x_m"] - v["x_m"], target["y_m"] - v["y_m"]) < FOV_M:
                    target["sigma"] = 1.0
                    target["last_seen_s"] = round(self.t, 3)

    # -------------------------------------------------------------- DaemonControl

    def state(self) -> dict[str, Any]:
        targets = []
        for tg in self.targets.values():
            s = tg["sigma"]
            targets.append({**tg, "cov_xy": [s * 0.6, s * 0.1, s * 0.4],
                            "lost": math.sqrt(s) > FOV_M,
                            "status": self.statuses.get(tg["id"], "confirmed")})
        return {
            "t": round(self.t, 3), "unix_s": time.time(), "speedup": 1.0, "advisory": False,
            "origin": {"lat_deg": 78.93, "lon_deg": 11.92}, "operating_radius_m": 2000.0,
            "vehicles": [{**v, "track": list(v["track"])} for v in self.vehicles],
            "targets": targets, "boat": {"x_m": 100.0 + self.t, "y_m": -50.0},
            "fov_radius_m": FOV_M,
            "plan": {"t": 0.0, "routes": {v["id"]: v["route"] for v in self.vehicles},
                     "status": "optimal", "solve_time_s": 0.01},
            "wind": {"wx_m_s": 12.0, "wy_m_s": 0.0, "speed_m_s": 12.0, "from_deg": 270.0,
                     "source": "vehicles", "vehicles": ["uav1", "uav2"],
                     "label": "12.0 m/s from 270° (vehicles uav1,uav2)", "planning": True},
            "events": list(self._events),
            **self._tracker(),
        }

    def _tracker(self) -> dict[str, Any]:
        tracks = [{"id": tid, "status": self.statuses.get(tid, "confirmed"),
                   "x_m": tg["x_m"], "y_m": tg["y_m"], "sigma_m2": tg["sigma"],
                   "existence": 0.5 if tid in ("B", "C") else 1.0, "t_s": round(self.t, 3)}
                  for tid, tg in self.targets.items()]
        tracks.append({"id": "N7", "status": "tentative", "x_m": -900.0, "y_m": 900.0,
                       "sigma_m2": 400.0, "existence": 0.3, "t_s": round(self.t, 3)})
        counts = {s: sum(1 for t in tracks if t["status"] == s)
                  for s in ("confirmed", "tentative", "prior")}
        cells = [{"id": f"S{k}", "x_m": -1000.0 + 500.0 * (k % 3),
                  "y_m": -1000.0 + 500.0 * (k // 3), "size_m": 500.0,
                  "value_m2": round((k + 1) * (10.0 + self.t), 1), "last_covered_s": None}
                 for k in range(9)]
        return {"tracks": tracks, "track_counts": counts, "search_cells": cells}

    async def _iterate(self, q: asyncio.Queue[dict[str, Any] | None]) -> AsyncIterator[
            dict[str, Any]]:
        try:
            while (line := await q.get()) is not None:
                yield line
        finally:
            self._subscribers.remove(q)

    def subscribe(self) -> AsyncIterator[dict[str, Any]]:
        q: asyncio.Queue[dict[str, Any] | None] = asyncio.Queue()
        self._subscribers.append(q)
        return self._iterate(q)

    async def add_target(self, target_id: str | None, *, x_m: float | None = None,
                         y_m: float | None = None, lat_deg: float | None = None,
                         lon_deg: float | None = None, vx_m_s: float = 0.0,
                         vy_m_s: float = 0.0, sigma0: float | None = None) -> dict[str, Any]:
        self.calls.append(("add", target_id, x_m, y_m, lat_deg, lon_deg, vx_m_s, vy_m_s,
                           sigma0))
        if self.refuse:
            return {"ok": False, "error": self.refuse}
        if target_id in self.targets:
            return {"ok": False, "error": f"target {target_id} exists"}
        if target_id is None:
            target_id = f"T{self._next_id}"
            self._next_id += 1
        if x_m is None or y_m is None:
            assert lat_deg is not None and lon_deg is not None
            x_m = (lon_deg - 11.92) * 111_320.0 * math.cos(math.radians(78.93))
            y_m = (lat_deg - 78.93) * 111_320.0
        self._new_target(target_id, x_m, y_m, vx_m_s, vy_m_s,
                         10.0 if sigma0 is None else sigma0)
        self.emit("target_added", target=target_id, x_m=x_m, y_m=y_m)
        # The "next plan" puts the new target first on the vehicle with the shortest route.
        v = min(self.vehicles, key=lambda v: len(v["route"]))
        v["route"] = [target_id, *v["route"]]
        self.emit("plan", routes={u["id"]: u["route"] for u in self.vehicles},
                  solve_time_s=0.01)
        return {"ok": True, "error": None, "target": target_id}

    async def move_target(self, target_id: str, *, x_m: float | None = None,
                          y_m: float | None = None, lat_deg: float | None = None,
                          lon_deg: float | None = None,
                          sigma0: float | None = None) -> dict[str, Any]:
        self.calls.append(("move", target_id, x_m, y_m, lat_deg, lon_deg))
        if self.refuse:
            return {"ok": False, "error": self.refuse}
        if target_id not in self.targets:
            return {"ok": False, "error": f"unknown target {target_id}"}
        if x_m is not None and y_m is not None:
            self.targets[target_id].update(x_m=x_m, y_m=y_m,
                                           sigma=10.0 if sigma0 is None else sigma0)
        self.emit("target_moved", target=target_id)
        t = self.targets[target_id]
        return {"ok": True, "error": None, "target": target_id, "x_m": t["x_m"],
                "y_m": t["y_m"], "sigma": t["sigma"]}

    async def remove_target(self, target_id: str) -> dict[str, Any]:
        self.calls.append(("remove", target_id))
        if self.refuse:
            return {"ok": False, "error": self.refuse}
        if self.targets.pop(target_id, None) is None:
            return {"ok": False, "error": f"unknown target {target_id}"}
        self.emit("target_removed", target=target_id)
        return {"ok": True, "error": None, "target": target_id}

    async def vehicle_action(self, vehicle_id: str, action: str) -> dict[str, Any]:
        self.calls.append(("vehicle", vehicle_id, action))
        if self.refuse:
            return {"ok": False, "error": self.refuse}
        assert action in VEHICLE_ACTIONS
        for v in self.vehicles:
            if v["id"] == vehicle_id:
                return self._act(v, action)
        return {"ok": False, "error": f"unknown vehicle {vehicle_id}"}

    def _act(self, v: dict[str, Any], action: str) -> dict[str, Any]:
        """As the daemon answers: released/home/active, or refused with the reason."""
        after = {"release": "released", "rtl": "home", "resume": "active",
                 "launch": "active"}[action]
        if v["status"] == after and action != "launch":
            return {"ok": False, "error": f"vehicle {v['id']} is {after} already",
                    "vehicle": v["id"], "status": v["status"]}
        v["status"] = after
        if after != "active":
            v["target"], v["route"] = None, []
        self.emit(action, vehicle=v["id"])
        return {"ok": True, "error": None, "vehicle": v["id"], "status": after,
                "what": f"vehicle {v['id']} {after}"}

    async def fleet_action(self, action: str) -> dict[str, Any]:
        self.calls.append(("fleet", action))
        if self.refuse:
            return {"ok": False, "error": self.refuse}
        results = [self._act(v, action) for v in self.vehicles]
        done = sum(1 for r in results if r["ok"])
        return {"ok": True, "error": None, "action": action, "results": results,
                "done": done, "refused": len(results) - done}


class ServerThread:
    """A ControlServer over a FakeControl on 127.0.0.1:0, run by its own event loop in a
    thread; with ``tick_s`` the fake world advances in real time (for the browser)."""

    def __init__(self, tick_s: float | None = None, token: str = "s3cret-token",
                 push_hz: float = 5.0, control: Any = None, tiles: Any = None) -> None:
        self.control: Any = control if control is not None else FakeControl()
        self.token = token
        self.tick_s = tick_s
        self.push_hz = push_hz
        self.tiles = tiles  # a TileArchive (control/tiles/) served as /tiles/{z}/{x}/{y}
        self.url = ""
        self.loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        try:
            self.loop.run_until_complete(self._main())
        except BaseException as exc:  # reported to start()
            self._error = exc
            self._ready.set()

    async def _main(self) -> None:
        self._stop = asyncio.Event()
        control: DaemonControl = self.control
        server = ControlServer(control, "127.0.0.1", 0, self.token, push_hz=self.push_hz,
                               tiles=self.tiles)
        await server.start()
        self.server = server
        self.url = server.url
        self._ready.set()
        try:
            while not self._stop.is_set():
                if self.tick_s is None:
                    await self._stop.wait()
                    break
                await asyncio.sleep(self.tick_s)
                self.control.advance(self.tick_s)
        finally:
            if hasattr(self.control, "close"):
                self.control.close()
            await server.stop()

    def call(self, fn: Any) -> Any:
        """Run ``fn()`` on the server's loop (thread-safe access to the fake)."""
        async def wrapper() -> Any:
            return fn()
        return asyncio.run_coroutine_threadsafe(wrapper(), self.loop).result(5.0)

    def __enter__(self) -> ServerThread:
        self._thread.start()
        if not self._ready.wait(10.0):
            raise RuntimeError("control server did not start")
        if self._error is not None:
            raise RuntimeError(f"control server failed: {self._error!r}")
        return self

    def __exit__(self, *exc: object) -> None:
        stop = self._stop
        if stop is not None and self.loop.is_running():
            self.loop.call_soon_threadsafe(stop.set)
        self._thread.join(10.0)
        self.loop.close()


# ------------------------------------------------------------------ tests of the fake itself


def test_fake_vehicles_move_and_targets_drift() -> None:
    fake = FakeControl()
    before = fake.state()
    for _ in range(20):
        fake.advance(0.5)
    after = fake.state()
    for v0, v1 in zip(before["vehicles"], after["vehicles"], strict=True):
        assert math.hypot(v1["x_m"] - v0["x_m"], v1["y_m"] - v0["y_m"]) > 100.0
        assert len(v1["track"]) > len(v0["track"])
    a0 = next(t for t in before["targets"] if t["id"] == "A")
    a1 = next(t for t in after["targets"] if t["id"] == "A")
    assert a1["x_m"] - a0["x_m"] > 4.0


def test_fake_journal_reaches_subscribers() -> None:
    async def main() -> list[dict[str, Any]]:
        fake = FakeControl()
        got: list[dict[str, Any]] = []

        async def reader() -> None:
            async for line in fake.subscribe():
                got.append(line)

        task = asyncio.create_task(reader())
        await asyncio.sleep(0)
        reply = await fake.add_target(None, x_m=1.0, y_m=2.0)
        assert reply["ok"] and reply["target"] == "T1"
        fake.close()
        await asyncio.wait_for(task, 2.0)
        return got

    events = asyncio.run(main())
    assert [e["event"] for e in events] == ["target_added", "plan"]
