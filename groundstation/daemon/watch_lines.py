"""The ship watch as the operator reads it (console status, API): the ship, each vehicle's
endurance and the time it must turn home, the spares and the next relief, the alarms
(``core/watch.py``'s :class:`~groundstation.core.watch.WatchView`; docs/ship.md)."""

from __future__ import annotations

import math
from typing import Any

from domain.geodesy import compass_deg_from_enu_rad
from groundstation.core.watch import WatchView

__all__ = ["ship_text", "watch_dict", "watch_rows"]


def ship_text(view: WatchView) -> str:
    """``ship at (1200, 3400) m, 10.0 m/s to 090 deg, fix 1 s old (+-6 m)``."""
    ship = view.ship
    if ship is None:
        return "ship: no fix yet"
    speed = math.hypot(ship.vx_m_s, ship.vy_m_s)
    course = _course_deg(ship.vx_m_s, ship.vy_m_s)
    age = "never" if math.isinf(ship.fix_age_s) else f"{ship.fix_age_s:.0f} s old"
    return (f"ship at ({ship.x_m:.0f}, {ship.y_m:.0f}) m, {speed:.1f} m/s to {course:03.0f} "
            f"deg, fix {age} (+-{ship.sigma_m:.0f} m)")


def watch_rows(view: WatchView, t_s: float) -> list[tuple[str, str, str, str, str, str]]:
    """Per vehicle with an energy model: id, charge %, drain %/min (source), minutes to
    its reserve, the mission time it must turn home (and in how long), can it reach the
    ship."""
    rows = []
    for vehicle, e in sorted(view.energy.items()):
        drain = f"{e.rate_pct_min:.2f}" + ("" if e.source == "reported" else " (assumed)")
        left = f"{max(0.0, e.endurance_left_s) / 60.0:.0f}"
        turn = "-" if e.turn_home_s is None else (
            f"t={e.turn_home_s:.0f} (in {max(0.0, e.turn_home_s - t_s) / 60.0:.0f} min)")
        rows.append((vehicle, f"{e.remaining_pct:.0f}", drain, left, turn,
                     "yes" if e.reachable else "NO"))
    return rows


def watch_dict(view: WatchView) -> dict[str, Any]:
    """The watch as JSON for the API and the live page."""
    ship = view.ship
    return {
        "ship": None if ship is None else {
            "t": ship.t_s, "x_m": ship.x_m, "y_m": ship.y_m, "vx_m_s": ship.vx_m_s,
            "vy_m_s": ship.vy_m_s, "sigma_m": ship.sigma_m,
            "fix_age_s": None if math.isinf(ship.fix_age_s) else ship.fix_age_s,
            "track": [[ship.x_m + ship.vx_m_s * dt, ship.y_m + ship.vy_m_s * dt]
                      for dt in (0.0, 300.0, 600.0)],
            "speed_m_s": math.hypot(ship.vx_m_s, ship.vy_m_s),
            "course_deg": _course_deg(ship.vx_m_s, ship.vy_m_s),
        },
        "energy": {
            v: {"remaining_pct": e.remaining_pct, "rate_pct_min": e.rate_pct_min,
                "rate_sd_pct_min": e.rate_sd_pct_min, "source": e.source,
                "endurance_left_s": e.endurance_left_s, "return_s": e.return_s,
                "turn_home_t": e.turn_home_s, "reachable": e.reachable}
            for v, e in sorted(view.energy.items())
        },
        "spares": list(view.spares),
        "on_station": view.on_station,
        "planned_on_station": view.planned_on_station,
        "next_relief": None if view.next_relief is None else {
            "vehicle": view.next_relief[0], "t": view.next_relief[1]},
        "alarms": list(view.alarms),
        "reliefs": view.reliefs,
    }


def _course_deg(vx_m_s: float, vy_m_s: float) -> float:
    """The course over ground, compass degrees, of an ENU velocity."""
    return compass_deg_from_enu_rad(math.atan2(vy_m_s, vx_m_s))
