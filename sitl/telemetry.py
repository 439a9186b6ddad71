"""Telemetry of a simulated ArduPlane: message rates and message construction (sans-IO).

Rates: every stream runs at 1 Hz of simulated time unrequested (ArduPlane's SR0_* defaults
in SITL give ~1 Hz to a new ground station). REQUEST_DATA_STREAM sets the rate of a group
(ArduPilot's grouping: EXTENDED_STATUS = SYS_STATUS, GPS_RAW_INT, MISSION_CURRENT,
NAV_CONTROLLER_OUTPUT, EXTENDED_SYS_STATE; POSITION = GLOBAL_POSITION_INT; EXTRA1 =
ATTITUDE; EXTRA2 = VFR_HUD; EXTRA3 = SYSTEM_TIME, BATTERY_STATUS, WIND (ArduPlane's
STREAM_EXTRA3 has WIND, SR*_EXTRA3 1 Hz by default); ALL = every group);
SET_MESSAGE_INTERVAL sets one message (interval -1 disables, 0 restores the default).
HEARTBEAT is always 1 Hz.

Adaptive flow control, as ArduPilot's ``GCS_MAVLINK::handle_radio_status``: each
RADIO_STATUS (from the vehicle's own radio) moves ``slowdown_s`` by its ``txbuf`` (% free of
the radio's serial buffer): < 20: +60 ms, < 50: +20 ms (up to 2 s), > 95: -40 ms (while
above 0.2 s), > 90: -20 ms (not below 0); ``slowdown_s`` is added to every stream's
interval (``get_reschedule_interval_ms``), HEARTBEAT excepted.
"""

from __future__ import annotations

import math

from groundstation.mavlink.codec import mavlink2

__all__ = ["STREAM_GROUPS", "StreamScheduler"]

M = mavlink2
HEARTBEAT = M.MAVLINK_MSG_ID_HEARTBEAT
STREAM_GROUPS: dict[int, tuple[int, ...]] = {
    M.MAV_DATA_STREAM_EXTENDED_STATUS: (
        M.MAVLINK_MSG_ID_SYS_STATUS,
        M.MAVLINK_MSG_ID_GPS_RAW_INT,
        M.MAVLINK_MSG_ID_MISSION_CURRENT,
        M.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT,
        M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
    ),
    M.MAV_DATA_STREAM_POSITION: (M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,),
    M.MAV_DATA_STREAM_EXTRA1: (M.MAVLINK_MSG_ID_ATTITUDE,),
    M.MAV_DATA_STREAM_EXTRA2: (M.MAVLINK_MSG_ID_VFR_HUD,),
    M.MAV_DATA_STREAM_EXTRA3: (
        M.MAVLINK_MSG_ID_SYSTEM_TIME,
        M.MAVLINK_MSG_ID_BATTERY_STATUS,
        M.MAVLINK_MSG_ID_WIND,
    ),
}
DEFAULT_INTERVALS_S: dict[int, float] = {HEARTBEAT: 1.0, M.MAVLINK_MSG_ID_HOME_POSITION: 5.0}
for _group in STREAM_GROUPS.values():
    for _msg_id in _group:
        DEFAULT_INTERVALS_S[_msg_id] = 1.0
STREAMABLE = frozenset(DEFAULT_INTERVALS_S)
"""Message ids the simulator can stream (SET_MESSAGE_INTERVAL accepts these)."""


class StreamScheduler:
    """Next-due times per message id in simulated seconds."""

    def __init__(self, t_s: float) -> None:
        self.intervals_s: dict[int, float | None] = dict(DEFAULT_INTERVALS_S)
        self._next_s: dict[int, float] = {m: t_s for m in self.intervals_s}
        self._earliest_s = t_s
        """No stream is due before this (a lower bound of the enabled next-due times): exact
        after each full :meth:`due` pass, lowered by :meth:`set_interval`; :meth:`due`
        before it returns at once."""
        self.slowdown_s = 0.0
        """Added to every stream interval but HEARTBEAT's (ArduPilot's
        ``stream_slowdown_ms``, driven by RADIO_STATUS)."""

    def radio_status(self, txbuf_pct: int) -> None:
        """ArduPilot's adaptive flow control on one RADIO_STATUS (see the module)."""
        ms = round(self.slowdown_s * 1000)
        if txbuf_pct < 20 and ms < 2000:
            ms += 60
        elif txbuf_pct < 50 and ms < 2000:
            ms += 20
        elif txbuf_pct > 95 and ms > 200:
            ms -= 40
        elif txbuf_pct > 90 and ms != 0:
            ms = ms - 20 if ms > 20 else 0
        self.slowdown_s = ms / 1000.0

    def set_interval(self, msg_id: int, interval_s: float | None, t_s: float) -> bool:
        """Set one message's interval (None disables); False for a message not streamable."""
        if msg_id not in STREAMABLE:
            return False
        self.intervals_s[msg_id] = interval_s
        self._next_s[msg_id] = t_s
        self._earliest_s = min(self._earliest_s, t_s)
        return True

    def set_default(self, msg_id: int, t_s: float) -> bool:
        """Restore the default interval of one message."""
        return self.set_interval(msg_id, DEFAULT_INTERVALS_S.get(msg_id), t_s)

    def set_group(self, stream_id: int, rate_hz: float, start: bool, t_s: float) -> None:
        """REQUEST_DATA_STREAM: rate of a group (or all), stopped when not ``start``."""
        groups = (
            STREAM_GROUPS.values()
            if stream_id == M.MAV_DATA_STREAM_ALL
            else ([STREAM_GROUPS[stream_id]] if stream_id in STREAM_GROUPS else [])
        )
        interval = 1.0 / rate_hz if start and rate_hz > 0 else None
        for group in groups:
            for msg_id in group:
                self.set_interval(msg_id, interval, t_s)

    def due(self, t_s: float) -> list[int]:
        """Message ids due at ``t_s`` (each advances by whole intervals, no burst catch-up)."""
        if t_s + 1e-9 < self._earliest_s:
            return []  # nothing is due: most physics steps
        out: list[int] = []
        earliest_s = math.inf
        for msg_id, interval in self.intervals_s.items():
            if interval is None:
                continue
            nxt = self._next_s.get(msg_id, t_s)
            if t_s + 1e-9 >= nxt:
                out.append(msg_id)
                if msg_id != HEARTBEAT:
                    interval += self.slowdown_s
                nxt += interval
                if nxt <= t_s:
                    nxt = t_s + interval
                self._next_s[msg_id] = nxt
            if nxt < earliest_s:
                earliest_s = nxt
        self._earliest_s = earliest_s
        return out
