"""ArduPlane-like flight logic: modes, mission execution and guided flight (sans-IO).

Facts reproduced (design.md, "MAVLink facts"; ArduPlane's commands_logic.cpp):

* each item start sends STATUSTEXT "Mission: N <name>"; each finished nav command sends
  MISSION_ITEM_REACHED N once;
* NAV_WAYPOINT ends within WP_RADIUS (or param2 if > 0) - "Reached waypoint #N dist Xm" -
  or when the finish line through the point is crossed - "Passed waypoint #N dist Xm";
  the line is normal to the leg from the previous waypoint, unless the vehicle is already
  past it when the leg starts (a jump, a set-current, a new mission): then the leg starts
  where the vehicle is (ArduPlane's ``set_next_WP``), so a waypoint is never passed at once;
* NAV_LOITER_TIME flies WP_LOITER_RAD (param3 only gives the sense: < 0 counter-clockwise),
  its timer starts once on the circle, end "Loiter time complete";
  NAV_LOITER_UNLIM honours param3 and never ends; NAV_LOITER_TURNS param1 turns at param3;
* radii are flown ``RADIUS_FACTOR`` = 1.15 times larger than commanded (and never tighter
  than the airframe's minimum turn radius);
* after the last item: "Mission complete, changing mode to RTL"; NAV_RETURN_TO_LAUNCH
  switches to RTL; RTL loiters over home at ALT_HOLD_RTL (cm) and RTL_RADIUS/WP_LOITER_RAD;
* a re-uploaded mission does not stop the active item (it is a copy); set-current to any
  seq, the same one included, restarts there at once;
* GUIDED loiters at the guided point; MISSION_ITEM_REACHED 0 on arrival;
* MANUAL, STABILIZE, TRAINING, ACRO and FBWA with no RC input (SITL's default: throttle
  closed, sticks centred) glide wings level until they hit the ground;
* on the ground nothing flies except AUTO on a NAV_TAKEOFF item while armed (ArduPlane
  suppresses the throttle on the ground otherwise): a plane that came down stays put in
  AUTO, RTL, LOITER or GUIDED;
* a NAV_TAKEOFF climbs out at ``CLIMB_OUT_AIRSPEED_M_S`` = 28 m/s, faster than the cruise
  (AIRSPEED_CRUISE, 22 m/s): ArduPlane flies its take-off at the take-off throttle
  (TKOFF_THR_MAX), and ArduPilot SITL's plane (3 vehicles, floe's launch mission, measured
  in issue 25) climbed out at 27.6-28.1 m/s airspeed (VFR_HUD) before settling to 22 once
  the take-off item completed; the figure is that measurement, not derived. A ground
  station that planned with the airspeed it measured at the join saw the climb-out's
  (docs/wind.md, "The first leg").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from domain.fault_spec import SIM_MODES
from domain.geodesy import GeoOrigin, wrap_pi
from domain.modes import ArduPlaneMode
from groundstation.mavlink.codec import mavlink2
from sitl.airframe import GLIDE, GROUND, STRAIGHT, Airframe, Guidance
from sitl.mission_store import MissionStore, StoredItem
from sitl.params import ParamStore
from sitl.statustext import StatusTextFactory

__all__ = [
    "CLIMB_OUT_AIRSPEED_M_S",
    "GLIDE_MODES",
    "MODE_NAMES",
    "RADIUS_FACTOR",
    "Autopilot",
    "NavTarget",
]

M = mavlink2
RADIUS_FACTOR = 1.15
CLIMB_OUT_AIRSPEED_M_S = 28.0
"""Airspeed of a NAV_TAKEOFF climb-out (module docstring; ArduPilot SITL: 27.6-28.1 m/s)."""
# the modes the built-in vehicle flies (domain.fault_spec.SIM_MODES), number -> name
MODE_NAMES: dict[int, str] = {number: name for name, number in SIM_MODES.items()}
_M = ArduPlaneMode
MANUAL, STABILIZE, FBWA, AUTO, RTL = _M.MANUAL, _M.STABILIZE, _M.FBWA, _M.AUTO, _M.RTL
LOITER, GUIDED, INITIALISING = _M.LOITER, _M.GUIDED, _M.INITIALISING
FLYING_MODES = frozenset({AUTO, RTL, LOITER, GUIDED, _M.TAKEOFF})
# pilot modes: with no RC input (throttle closed, sticks centred) the plane glides down
GLIDE_MODES = frozenset({MANUAL, STABILIZE, _M.TRAINING, _M.ACRO, FBWA})
_ON_CIRCLE_FRACTION = 0.1
_ON_CIRCLE_MIN_M = 10.0


@dataclass
class NavTarget:
    """The nav command being flown (a copy: re-uploads do not change it)."""

    kind: str  # waypoint | loiter_unlim | loiter_time | loiter_turns | takeoff | land | hold
    seq: int
    x_m: float
    y_m: float
    alt_m: float
    radius_m: float = 0.0
    clockwise: bool = True
    duration_s: float = 0.0
    turns: float = 0.0
    acceptance_m: float = 0.0
    prev_x_m: float = 0.0
    prev_y_m: float = 0.0
    on_circle_t_s: float | None = None
    angle_rad: float = 0.0
    last_bearing_rad: float | None = None
    reached: bool = False


class Autopilot:
    """Mode and mission logic of one vehicle; ``update`` is called every physics step."""

    def __init__(
        self,
        store: MissionStore,
        params: ParamStore,
        text: StatusTextFactory,
        origin: GeoOrigin,
        home_xy_m: tuple[float, float],
        home_amsl_m: float,
        cruise_speed_m_s: float,
        rally_points: Callable[[], list[StoredItem]] | None = None,
    ) -> None:
        self.store = store
        self.rally_points = rally_points or list
        self.params = params
        self.text = text
        self.origin = origin
        self.home_xy_m = home_xy_m
        self.home_amsl_m = home_amsl_m
        self.mode: int = INITIALISING
        self.armed = False
        self.current_seq = 0
        self.mission_complete = False
        self.nav: NavTarget | None = None
        self.speed_cmd_m_s = cruise_speed_m_s
        self.alt_hold_m = 0.0
        self.current_changed = False
        self._jump_counts: dict[int, int] = {}
        self._last_guidance: Guidance | None = None
        """What :meth:`_guidance_to` returned last (it says what invalidates it)."""

    def airspeed_cmd_m_s(self) -> float:
        """The airspeed to fly: the climb-out's while a NAV_TAKEOFF flies in AUTO, else the
        cruise (or the DO_CHANGE_SPEED) command."""
        nav = self.nav
        if self.mode == AUTO and nav is not None and nav.kind == "takeoff":
            return max(CLIMB_OUT_AIRSPEED_M_S, self.speed_cmd_m_s)
        return self.speed_cmd_m_s

    # ----------------------------------------------------------------- helpers
    def _texts(self, text: str, severity: int = M.MAV_SEVERITY_INFO) -> list[Any]:
        return self.text.make(text, severity)

    def _loiter_radius(self, commanded_m: float) -> tuple[float, bool]:
        """(flown radius, clockwise) for a signed commanded radius; |r| <= 1 m means
        WP_LOITER_RAD (whose sign gives the sense: negative is counter-clockwise)."""
        if abs(commanded_m) <= 1.0:
            default = self.params.get("WP_LOITER_RAD")
            ccw = commanded_m < 0.0 or default < 0.0
            return RADIUS_FACTOR * abs(default), not ccw
        return RADIUS_FACTOR * abs(commanded_m), commanded_m >= 0.0

    def _item_xy_alt(self, item: StoredItem, af: Airframe) -> tuple[float, float, float]:
        if item.x == 0 and item.y == 0:
            x_m, y_m = af.x_m, af.y_m
        else:
            x_m, y_m, _ = self.origin.to_local(item.lat_deg, item.lon_deg)
        alt_m = item.z
        if item.frame in (M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT):
            alt_m = item.z - self.home_amsl_m
        if item.x == 0 and item.y == 0 and item.z == 0:
            alt_m = af.alt_m
        return x_m, y_m, alt_m

    def _set_current(self, seq: int) -> None:
        if seq != self.current_seq:
            self.current_changed = True
        self.current_seq = seq

    # ------------------------------------------------------------------- modes
    def set_mode(self, mode: int, af: Airframe) -> list[Any]:
        """Enter ``mode`` (known to be valid) and set up its target."""
        out: list[Any] = []
        previous, self.mode = self.mode, mode
        self.nav = None
        if mode == AUTO:
            if previous == AUTO and self.mission_complete:
                return out
            # AP_Mission::resume(): a completed mission starts again from item 1, otherwise
            # the current item restarts
            seq = 1 if self.mission_complete else max(1, self.current_seq)
            self.mission_complete = False
            if seq == 1:
                self._jump_counts.clear()
            out += self.start_item(seq, af)
        elif mode == RTL:
            out += self._start_rtl(af)
        elif mode in (LOITER, GUIDED):
            radius, cw = self._loiter_radius(0.0)
            self.nav = NavTarget("hold", 0, af.x_m, af.y_m, af.alt_m, radius, cw)
        else:
            self.alt_hold_m = af.alt_m
        return out

    def _start_rtl(self, af: Airframe) -> list[Any]:
        """ArduPlane's do_RTL at RTL entry: the target (the best rally point or home) is
        computed once, here; a home moved later takes effect at the next RTL entry."""
        alt_cm = self.params.get("ALT_HOLD_RTL")
        alt_m = af.alt_m if alt_cm < 0 else alt_cm / 100.0
        rtl_radius = self.params.get("RTL_RADIUS")
        radius, cw = self._loiter_radius(rtl_radius)
        x_m, y_m = self.home_xy_m
        rally = self.best_rally_point(af)
        if rally is not None:
            x_m, y_m, alt_m = rally
        self.nav = NavTarget("hold", 0, x_m, y_m, alt_m, radius, cw)
        return []

    def best_rally_point(self, af: Airframe) -> tuple[float, float, float] | None:
        """AP_Rally::calc_best_rally_or_home_location: the nearest rally point, unless
        RALLY_LIMIT_KM > 0 and it is farther than that (then home); with RALLY_INCL_HOME 1
        only if it is nearer than home. None: home. (x_m, y_m, alt_m above home)."""
        best: tuple[float, float, float] | None = None
        best_m = math.inf
        for item in self.rally_points():
            if item.x == 0 and item.y == 0:
                continue  # AP_Rally's sanity check: (0, 0) is no rally point
            x_m, y_m, _ = self.origin.to_local(item.lat_deg, item.lon_deg)
            dist_m = af.distance_to_m(x_m, y_m)
            if dist_m < best_m:
                alt_m = item.z - self.home_amsl_m if item.frame in (
                    M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT) else item.z
                best, best_m = (x_m, y_m, alt_m), dist_m
        if best is None:
            return None
        limit_km = self.params.get("RALLY_LIMIT_KM")
        if limit_km > 0 and best_m > 1000.0 * limit_km:
            return None
        if int(self.params.get("RALLY_INCL_HOME")) and best_m >= af.distance_to_m(*self.home_xy_m):
            return None
        return best

    def set_guided_target(
        self, x_m: float, y_m: float, alt_m: float, radius_signed_m: float
    ) -> None:
        """GUIDED destination: loiter there (radius 0 -> WP_LOITER_RAD)."""
        radius, cw = self._loiter_radius(radius_signed_m)
        self.nav = NavTarget("hold", 0, x_m, y_m, alt_m, radius, cw)

    # ----------------------------------------------------------------- mission
    def set_current_item(self, seq: int, af: Airframe) -> tuple[bool, list[Any]]:
        """MISSION_SET_CURRENT / DO_SET_MISSION_CURRENT: restart at ``seq`` (same seq too)."""
        if not 0 <= seq < len(self.store):
            return False, []
        seq = max(1, seq)
        self.mission_complete = False
        self.current_changed = True
        if self.mode == AUTO:
            return True, self.start_item(seq, af)
        self.current_seq = seq
        return True, []

    def start_item(self, seq: int, af: Airframe) -> list[Any]:
        """Start the command at ``seq``; do-commands run at once and the next one starts."""
        out: list[Any] = []
        for _ in range(len(self.store) + 2):  # bounded walk over do-commands and jumps
            if seq >= len(self.store):
                return out + self._mission_end(af)
            self._set_current(seq)
            item = self.store.items[seq]
            out += self._texts(f"Mission: {seq} {item.name}")
            if item.is_nav:
                out += self._start_nav(seq, item, af)
                return out
            seq = self._run_do_command(seq, item)
        return out + self._mission_end(af)

    def _run_do_command(self, seq: int, item: StoredItem) -> int:
        if item.command == M.MAV_CMD_DO_CHANGE_SPEED and item.param2 > 0:
            lo, hi = self.params.get("AIRSPEED_MIN"), self.params.get("AIRSPEED_MAX")
            self.speed_cmd_m_s = max(lo, min(hi, item.param2))
        elif item.command == M.MAV_CMD_DO_JUMP:
            target, repeat = int(item.param1), int(item.param2)
            done = self._jump_counts.get(seq, 0)
            if 0 < target < len(self.store) and (repeat < 0 or done < repeat):
                self._jump_counts[seq] = done + 1
                return target
        return seq + 1

    def _start_nav(self, seq: int, item: StoredItem, af: Airframe) -> list[Any]:
        out: list[Any] = []
        if item.command == M.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            self.mode = RTL
            return out + self._start_rtl(af)
        x_m, y_m, alt_m = self._item_xy_alt(item, af)
        prev = (af.x_m, af.y_m)  # the finish line is through the point, normal to prev->point
        if self.nav is not None and self.nav.kind == "waypoint" and not _past_finish_line(
            (af.x_m, af.y_m), (self.nav.x_m, self.nav.y_m), (x_m, y_m)
        ):
            prev = (self.nav.x_m, self.nav.y_m)
        nav = NavTarget("waypoint", seq, x_m, y_m, alt_m, prev_x_m=prev[0], prev_y_m=prev[1])
        cmd = item.command
        if cmd == M.MAV_CMD_NAV_WAYPOINT:
            nav.acceptance_m = item.param2 if item.param2 > 0 else self.params.get("WP_RADIUS")
        elif cmd == M.MAV_CMD_NAV_LOITER_UNLIM:
            nav.kind = "loiter_unlim"
            nav.radius_m, nav.clockwise = self._loiter_radius(item.param3)
        elif cmd == M.MAV_CMD_NAV_LOITER_TIME:
            nav.kind = "loiter_time"
            radius, default_cw = self._loiter_radius(0.0)  # WP_LOITER_RAD, its sign too
            nav.radius_m, nav.clockwise = radius, item.param3 >= 0.0 and default_cw
            nav.duration_s = max(0.0, item.param1)
        elif cmd == M.MAV_CMD_NAV_LOITER_TURNS:
            nav.kind = "loiter_turns"
            nav.radius_m, nav.clockwise = self._loiter_radius(item.param3)
            nav.turns = max(0.0, item.param1)
        elif cmd == M.MAV_CMD_NAV_LOITER_TO_ALT:  # radius in param2; ends at once on the
            nav.kind = "loiter_turns"  # circle here (altitude is reached on the way)
            nav.radius_m, nav.clockwise = self._loiter_radius(item.param2)
            nav.turns = 0.0
        elif cmd == M.MAV_CMD_NAV_TAKEOFF:
            nav.kind = "takeoff"
            nav.x_m, nav.y_m = (
                af.x_m + 1e4 * math.cos(af.heading_rad),
                af.y_m + 1e4 * math.sin(af.heading_rad),
            )
        elif cmd == M.MAV_CMD_NAV_LAND:
            nav.kind = "land"
            nav.acceptance_m = 20.0
        self.nav = nav
        return out

    def _mission_end(self, af: Airframe) -> list[Any]:
        self.mission_complete = True
        self.nav = None
        if self.mode == AUTO:
            self.mode = RTL
            self._start_rtl(af)
            return self._texts("Mission complete, changing mode to RTL")
        return []

    def _advance(self, af: Airframe) -> list[Any]:
        assert self.nav is not None
        seq = self.nav.seq
        return [M.MAVLink_mission_item_reached_message(seq), *self.start_item(seq + 1, af)]

    # ------------------------------------------------------------------ update
    def _on_circle(self, nav: NavTarget, af: Airframe) -> bool:
        radius = max(nav.radius_m, af.min_turn_radius_m)
        tol = max(_ON_CIRCLE_MIN_M, _ON_CIRCLE_FRACTION * radius)
        return abs(af.distance_to_m(nav.x_m, nav.y_m) - radius) <= tol

    def update(self, t_s: float, af: Airframe) -> list[Any]:
        """Check the active command's end after a physics step; returns messages."""
        nav = self.nav
        if nav is None or af.on_ground:
            return []
        if nav.kind == "hold":
            if self.mode == GUIDED and not nav.reached and self._on_circle(nav, af):
                nav.reached = True
                return [M.MAVLink_mission_item_reached_message(0)]
            return []
        if self.mode != AUTO:
            return []
        dist_m = af.distance_to_m(nav.x_m, nav.y_m)
        if nav.kind == "waypoint":
            if dist_m <= nav.acceptance_m:
                return [
                    *self._texts(f"Reached waypoint #{nav.seq} dist {dist_m:.0f}m"),
                    *self._advance(af),
                ]
            if _past_finish_line((af.x_m, af.y_m), (nav.prev_x_m, nav.prev_y_m),
                                 (nav.x_m, nav.y_m)):
                return [
                    *self._texts(f"Passed waypoint #{nav.seq} dist {dist_m:.0f}m"),
                    *self._advance(af),
                ]
            return []
        if nav.kind == "takeoff":
            if af.alt_m >= nav.alt_m - 1.0:
                return [*self._texts(f"Takeoff complete at {af.alt_m:.2f}m"), *self._advance(af)]
            return []
        if nav.kind == "land":
            if dist_m <= nav.acceptance_m:
                nav.kind = "landing"
            return []
        if nav.kind == "landing":
            if af.alt_m <= 0.5:
                af.on_ground = True
                self.armed = False
                self.mission_complete = True
                return [
                    M.MAVLink_mission_item_reached_message(nav.seq),
                    *self._texts("Land complete"),
                ]
            return []
        if nav.kind in ("loiter_time", "loiter_turns"):
            return self._update_loiter(t_s, nav, af)
        return []

    def _update_loiter(self, t_s: float, nav: NavTarget, af: Airframe) -> list[Any]:
        if nav.on_circle_t_s is None:
            if self._on_circle(nav, af):
                nav.on_circle_t_s = t_s
                nav.last_bearing_rad = math.atan2(af.y_m - nav.y_m, af.x_m - nav.x_m)
            return []
        if nav.kind == "loiter_time":
            if t_s - nav.on_circle_t_s >= nav.duration_s:
                return [*self._texts("Loiter time complete"), *self._advance(af)]
            return []
        bearing = math.atan2(af.y_m - nav.y_m, af.x_m - nav.x_m)
        if nav.last_bearing_rad is not None:
            nav.angle_rad += abs(wrap_pi(bearing - nav.last_bearing_rad))
        nav.last_bearing_rad = bearing
        if nav.angle_rad >= 2.0 * math.pi * nav.turns:
            return [*self._texts("Loiter orbits complete"), *self._advance(af)]
        return []

    def guidance(self, af: Airframe) -> tuple[Guidance, float]:
        """(lateral guidance, altitude command) for the current mode and command."""
        if af.on_ground and not (
            self.armed and self.mode == AUTO and self.nav is not None and self.nav.kind == "takeoff"
        ):
            return GROUND, 0.0
        nav = self.nav
        if self.mode in GLIDE_MODES:
            return GLIDE, 0.0
        if self.mode not in FLYING_MODES or nav is None:
            return STRAIGHT, self.alt_hold_m
        if nav.kind in ("hold", "loiter_unlim", "loiter_time", "loiter_turns"):
            return self._guidance_to("loiter", nav, nav.radius_m, nav.clockwise), nav.alt_m
        if nav.kind == "landing":
            return self._guidance_to("point", nav), 0.0
        return self._guidance_to("point", nav), nav.alt_m

    def _guidance_to(self, kind: str, nav: NavTarget, radius_m: float = 0.0,
                     clockwise: bool = True) -> Guidance:
        """``Guidance(kind, nav.x_m, nav.y_m, radius_m, clockwise)``: the one returned last
        time while it is made of the very same values (compared by identity, so -0.0 and
        NaN are exact; a Guidance is immutable), else a new one. A step's guidance is
        usually the last step's: reusing it saves building one every step."""
        last = self._last_guidance
        if (last is not None and last.kind == kind and last.x_m is nav.x_m
                and last.y_m is nav.y_m and last.radius_m is radius_m
                and last.clockwise is clockwise):
            return last
        self._last_guidance = Guidance(kind, nav.x_m, nav.y_m, radius_m, clockwise)
        return self._last_guidance


def _past_finish_line(pos: tuple[float, float], prev: tuple[float, float],
                      point: tuple[float, float]) -> bool:
    """Whether ``pos`` is past the line through ``point`` normal to ``prev -> point``:
    ``(point - prev) . (pos - point) > 0`` (False for a leg shorter than 1 m)."""
    lx, ly = point[0] - prev[0], point[1] - prev[1]
    return math.hypot(lx, ly) > 1.0 and lx * (pos[0] - point[0]) + ly * (pos[1] - point[1]) > 0
