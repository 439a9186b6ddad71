"""The controller's geofence rules (vehicle/jobs.py fence_job, controller._fence_due): the
area's fence goes to a vehicle floe commands, at join and when the area moves, enabled as
ArduPlane expects; never to one its pilot took over."""

from __future__ import annotations

import math
from typing import Any

import pytest
from test_vehicle_controller import Rig

from domain.modes import ArduPlaneMode
from groundstation.core.area import OperatingArea
from groundstation.mavlink.fence_items import (
    CAPTURE_OVERSHOOT_M,
    FENCE_MOVE_M,
    FenceCircle,
    fence_circle,
    keep_in_m,
)
from groundstation.vehicle import controller_io as vio
from groundstation.vehicle.controller import VehicleState

S = VehicleState
AREA = FenceCircle(0.0, 0.0, 10300.0)


class FenceRig(Rig):
    """The controller test's vehicle, which also answers fence uploads (verified unless
    ``fence_ok`` is False) and has ArduPlane's fence parameters."""

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        self.params.update({"FENCE_TYPE": 0.0, "FENCE_ACTION": 0.0})
        self.fence_ok = True

    def _collect(self, out: list[vio.Output]) -> None:
        super()._collect(out)
        for o in out:
            if isinstance(o, vio.UploadFence):
                assert self.pending is None, "two exchanges at once"
                self.pending = o
                self.asked.append(o)

    def answer(self, result: Any) -> list[vio.Output]:
        """The base rig answers what it does not know with True: a fence upload gets its
        outcome here, a fence parameter is kept."""
        request = self.pending
        if isinstance(request, vio.UploadFence):
            result = vio.UploadOutcome(self.fence_ok, 0,
                                       None if self.fence_ok else "verify: item 0", 2)
        elif isinstance(request, vio.FenceParam):
            self.params[request.name] = request.value
        return super().answer(result)

    def fence_requests(self) -> list[Any]:
        return [r for r in self.asked if isinstance(r, vio.UploadFence | vio.FenceParam)]


def joined(rig: FenceRig) -> FenceRig:
    rig.run(4.0)
    assert rig.c.state is S.ACTIVE, rig.out
    return rig


def test_the_area_is_fenced_and_enabled_before_the_first_target_mission() -> None:
    rig = FenceRig()
    rig.feed(vio.FenceWanted(rig.t, AREA))
    joined(rig)
    rig.fly()
    rig.run(3.0)
    names = [(type(r).__name__, getattr(r, "name", None)) for r in rig.reads]
    assert ("ReadParam", "FENCE_TYPE") in names and ("ReadParam", "FENCE_ACTION") in names
    kinds = [(type(r).__name__, getattr(r, "name", None), getattr(r, "value", None))
             for r in rig.fence_requests()]
    # the polygon bit added, report-only made RTL, the items verified, then enabled
    assert kinds == [("FenceParam", "FENCE_TYPE", 4.0), ("FenceParam", "FENCE_ACTION", 1.0),
                     ("UploadFence", None, None), ("FenceParam", "FENCE_ENABLE", 1.0)]
    [upload] = [r for r in rig.asked if isinstance(r, vio.UploadFence)]
    assert upload.fence == AREA
    [line] = rig.journal("fence")
    assert line.fields["ok"] is True and line.fields["radius_m"] == AREA.radius_m
    assert rig.c.fence_held == AREA
    # the fence went first, the target mission after it
    order = [type(r).__name__ for r in rig.asked]
    assert order.index("UploadFence") < max(
        i for i, r in enumerate(rig.asked) if isinstance(r, vio.UploadMission))


def test_the_fence_follows_the_area_only_when_it_moved_more_than_the_rule_says() -> None:
    rig = joined(FenceRig())
    rig.feed(vio.FenceWanted(rig.t, AREA))
    rig.run(2.0)
    assert len([r for r in rig.asked if isinstance(r, vio.UploadFence)]) == 1
    rig.feed(vio.FenceWanted(rig.t, FenceCircle(FENCE_MOVE_M * 0.9, 0.0, AREA.radius_m)))
    rig.run(2.0)
    assert len([r for r in rig.asked if isinstance(r, vio.UploadFence)]) == 1
    moved = FenceCircle(FENCE_MOVE_M * 1.1, 0.0, AREA.radius_m)
    rig.feed(vio.FenceWanted(rig.t, moved))
    rig.run(2.0)
    uploads = [r for r in rig.asked if isinstance(r, vio.UploadFence)]
    assert [u.fence for u in uploads] == [AREA, moved]
    # parameters already right are not written again: only the enable after the upload
    later = rig.fence_requests()[rig.fence_requests().index(uploads[1]):]
    assert [getattr(r, "name", None) for r in later] == [None, "FENCE_ENABLE"]


def test_nothing_is_uploaded_or_enabled_to_a_vehicle_its_pilot_took_over() -> None:
    rig = joined(FenceRig())
    rig.feed(vio.FenceWanted(rig.t, AREA))
    rig.run(2.0)
    rig.run(6.0, mode=ArduPlaneMode.FBWA, mode_name="FBWA")
    assert rig.c.state is S.OVERRIDDEN
    before = len(rig.fence_requests())
    moved = FenceCircle(2000.0, 0.0, AREA.radius_m)
    rig.feed(vio.FenceWanted(rig.t, moved))
    rig.run(60.0)
    assert len(rig.fence_requests()) == before  # the pilot's vehicle: nothing sent
    # the pilot gives it back (AUTO): it is floe's again, and gets the area's fence
    rig.run(6.0, mode=ArduPlaneMode.AUTO, mode_name="AUTO")
    assert rig.c.state is S.ACTIVE
    assert [r.fence for r in rig.asked if isinstance(r, vio.UploadFence)][-1] == moved


def test_a_failed_fence_is_journalled_and_tried_again_later() -> None:
    rig = joined(FenceRig(fence_retry_s=30.0))
    rig.fence_ok = False
    rig.feed(vio.FenceWanted(rig.t, AREA))
    rig.run(5.0)
    assert [line.fields["ok"] for line in rig.journal("fence")] == [False]
    assert rig.c.fence_held is None
    rig.fence_ok = True
    rig.run(20.0)
    assert len(rig.journal("fence")) == 1  # not before fence_retry_s
    rig.run(15.0)
    assert [line.fields["ok"] for line in rig.journal("fence")] == [False, True]
    assert rig.c.fence_held == AREA


def test_an_autopilot_that_refuses_the_fence_is_asked_three_times_not_all_run() -> None:
    rig = joined(FenceRig(fence_retry_s=30.0))
    rig.fence_ok = False
    rig.feed(vio.FenceWanted(rig.t, AREA))
    rig.run(300.0, step_s=1.0)
    assert [line.fields["ok"] for line in rig.journal("fence")] == [False] * 3
    # a boat's area drifting in small steps is still the fence refused: not tried again
    for step in range(1, 5):
        rig.feed(vio.FenceWanted(rig.t, FenceCircle(20.0 * step, 0.0, AREA.radius_m)))
        rig.run(40.0, step_s=1.0)
    assert len(rig.journal("fence")) == 3
    # the area moved away from the refused fence: that fence is tried afresh
    rig.feed(vio.FenceWanted(rig.t, FenceCircle(500.0, 0.0, AREA.radius_m)))
    rig.run(5.0)
    assert len(rig.journal("fence")) == 4


@pytest.mark.parametrize("around_boat", [False, True])
def test_a_loiter_at_a_clipped_waypoint_stays_inside_the_fence_the_vehicle_holds(
    around_boat: bool,
) -> None:
    """The fence is the area itself; a waypoint far outside is clipped a loiter's room
    inside, and its loiter circle (plus the capture overshoot) stays inside the fence even
    when the boat moved the area by just under the re-upload distance since the fence went."""
    area = OperatingArea(2000.0, around_boat)
    area.boat_xy_m = (100.0, -50.0)
    held = fence_circle(area.center(), area.radius_m)
    assert held is not None and held.radius_m == 2000.0
    assert (held.x_m, held.y_m) == ((100.0, -50.0) if around_boat else (0.0, 0.0))
    if around_boat:  # the boat moved, the vehicle still holds the old fence
        area.boat_xy_m = (100.0 + FENCE_MOVE_M * 0.99, -50.0)
        assert not fence_circle(area.center(), area.radius_m).moved(held)  # type: ignore[union-attr]
    loiter_m = 150.0
    for bearing_deg in range(0, 360, 15):
        b = math.radians(bearing_deg + 7.0)
        far = (5000.0 * math.cos(b), 5000.0 * math.sin(b))
        x_m, y_m, clipped = area.clip(*far, keep_in_m(loiter_m, around_boat))
        assert clipped
        reach_m = math.hypot(x_m - held.x_m, y_m - held.y_m) + loiter_m + CAPTURE_OVERSHOOT_M
        assert reach_m <= held.radius_m + 1e-6, (bearing_deg, reach_m)
    # a waypoint already a loiter's room inside is left alone
    cx, cy = area.center()
    assert area.clip(cx + 1000.0, cy, keep_in_m(loiter_m, around_boat)) == (cx + 1000.0, cy, False)
