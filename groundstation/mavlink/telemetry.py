"""Sans-IO telemetry reducer: one vehicle's MAVLink stream -> a snapshot and events.

:class:`VehicleTelemetry` is fed every decoded message with the mission time it arrived
(``receive(msg, now_s)``) and keeps the vehicle's latest state in floe's frames:

* position: ``GLOBAL_POSITION_INT`` lat/lon (degE7) -> local ENU (x_m east, y_m north) with
  the mission :class:`GeoOrigin` (pymap3d, so cos(lat) is never forgotten); ``alt_m`` is the
  altitude above home (``relative_alt``, mm); velocity ``vx`` (north) / ``vy`` (east) cm/s
  -> ENU ``(ve, vn)``.
* heading: compass ``hdg`` (GLOBAL_POSITION_INT, cdeg; 65535 = unknown), VFR_HUD ``heading``
  (deg) or ATTITUDE ``yaw`` (rad, clockwise from north) -> ENU ``psi = pi/2 - hdg``, wrapped to
  [-pi, pi). The latest valid source wins.
* mode (HEARTBEAT ``custom_mode``, ArduPlane numbering), armed (``base_mode`` bit 128), mission
  progress (MISSION_CURRENT, MISSION_ITEM_REACHED), battery (SYS_STATUS, BATTERY_STATUS),
  pre-arm state (SYS_STATUS health bit 0x10000000, the best single "ready" signal), and
  SYS_STATUS's three sensor bitmasks as they came (``sensors``).
* GPS fix: GPS_RAW_INT ``fix_type``, ``satellites_visible``, ``eph`` (HDOP x 100) ->
  ``gps_fix`` (:mod:`.gps_message`: unknown values and garbage are None, garbage also an
  :class:`InvalidTelemetry`), ``last_gps_s``; a reboot forgets it.

Values that are NaN or out of range are never stored: they are dropped and reported as
:class:`InvalidTelemetry`. Messages from another system id, and HEARTBEATs of components
that are not an autopilot (cameras, ground stations on the same system id), are ignored.
A position older (``time_boot_ms``) than the last one (UDP reordering) is ignored as stale.

Reboots: ``time_boot_ms`` (any message that carries it) going back by more than
``reboot_backstep_ms`` makes a suspicion (``reboot_suspected`` in the snapshot; the value is
held back); it is a reboot when the following frames keep to the new timeline over
``reboot_frames`` frames and ``reboot_span_s``, or at once when the HEARTBEAT says the
autopilot is booting (``system_status`` MAV_STATE_BOOT or mode INITIALISING). Then
:class:`Rebooted` is emitted and the mission progress forgotten; a frame back on the old
timeline clears the suspicion (one stray frame is no reboot). A ``time_boot_ms`` ahead of
what the receive clock allows since the accepted frames is held back too (no suspicion of
a reboot; a GLOBAL_POSITION_INT carrying it does not set the order positions are kept in)
until frames keep to it the same way (:class:`~.evidence.RebootEvidence`). (A reboot
during a silence longer than the previous uptime is the case this cannot see.)

RADIO_STATUS and RADIO describe a telemetry radio, never the vehicle (a SiK radio injects
them, unsigned, with any system id): they are counted (``radio_messages``) and ignored, so
they never make the vehicle "heard" (``last_heard_s``).

HEARTBEAT ``system_status`` and EXTENDED_SYS_STATE ``landed_state`` are kept in the
snapshot. Messages of the system from another component are counted
(``foreign_messages``) and otherwise ignored.

WIND (the autopilot's own wind estimate, :mod:`.wind_message`) is checked frame by frame
(a bad one is an :class:`InvalidTelemetry`, counted in ``bad_wind``) and accepted over
several frames (:class:`~.evidence.WindEvidence`); each accepted value updates
``wind_xy_m_s`` and emits :class:`WindReported`. A reboot forgets it.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Literal

from domain.geodesy import GeoOrigin, enu_rad_from_compass_deg, wrap_pi
from domain.modes import ArduPlaneMode
from groundstation.mavlink.codec import MAVLinkMessage, mavlink2
from groundstation.mavlink.evidence import MAV_STATE_BOOT, RebootEvidence, WindEvidence
from groundstation.mavlink.gps_message import parse_gps_raw_int
from groundstation.mavlink.telemetry_events import (
    ARDUPLANE_MODES,
    Armed,
    BatteryBelowThreshold,
    Disarmed,
    InvalidTelemetry,
    MissionCurrentChanged,
    MissionItemReached,
    ModeChanged,
    PrearmChanged,
    Rebooted,
    StatusText,
    TelemetryEvent,
    VehicleSnapshot,
    WindReported,
    mode_name,
)
from groundstation.mavlink.wind_message import BadWindField, parse_wind_message

__all__ = [
    "ARDUPLANE_MODES",
    "Armed",
    "BatteryBelowThreshold",
    "Disarmed",
    "InvalidTelemetry",
    "LoiterEndDetector",
    "MissionCurrentChanged",
    "MissionItemReached",
    "ModeChanged",
    "PrearmChanged",
    "Rebooted",
    "StatusText",
    "TelemetryEvent",
    "VehicleSnapshot",
    "VehicleTelemetry",
    "WindReported",
    "mode_name",
]

PREARM_CHECK_BIT = 0x10000000  # MAV_SYS_STATUS_PREARM_CHECK
_ARMED_FLAG = 128  # MAV_MODE_FLAG_SAFETY_ARMED
_CUSTOM_MODE_FLAG = 1  # MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
_UINT16_UNKNOWN = 65535
_MAX_CURRENT_CA = 100_000
"""A battery current beyond 1000 A is no reading (cA on the wire)."""
_MISSION_STATE_MAX = 5  # MISSION_STATE_COMPLETE, the last MISSION_STATE value
_STATUSTEXT_CHUNK = 50
_MAX_SPEED_M_S = 150.0
_MAX_ALT_M = 20_000.0
RADIO_MESSAGES = frozenset({"RADIO_STATUS", "RADIO"})
"""Messages of a telemetry radio, not of the vehicle (ignored by the reducer)."""


# --------------------------------------------------------------------------- reducer


_SNAPSHOT_FIELDS = frozenset(f.name for f in fields(VehicleSnapshot))


def _evolve(snap: VehicleSnapshot, **changes: object) -> VehicleSnapshot:
    """``dataclasses.replace(snap, **changes)`` without running ``__init__`` again: every
    frame passes here (a handler gathers its changes into one copy), a flood's too, and
    ``replace`` rebuilds all 35 fields
    through ``__init__`` (6 against 72 us a call on a loaded host; the drain of a backlog is
    that much faster). The copy is as frozen as the original (the snapshot has no
    ``__post_init__``); a name that is not a field raises TypeError, as ``replace`` does."""
    if not changes.keys() <= _SNAPSHOT_FIELDS:
        raise TypeError(f"VehicleSnapshot has no field {sorted(changes.keys() - _SNAPSHOT_FIELDS)}")
    new: VehicleSnapshot = object.__new__(VehicleSnapshot)
    state = new.__dict__
    state.update(snap.__dict__)
    state.update(changes)
    return new


class VehicleTelemetry:
    """Reduce one vehicle's messages to a :class:`VehicleSnapshot` and events.

    ``battery_low_pct`` (and optionally ``battery_low_v``) trigger
    :class:`BatteryBelowThreshold` once per crossing; it re-arms when the level recovers
    ``battery_hysteresis_pct`` above.
    Incomplete chunked STATUSTEXTs are flushed after ``statustext_timeout_s``. Only the
    autopilot component ``component_id`` (1, MAV_COMP_ID_AUTOPILOT1; None: any) is listened
    to: a camera or companion computer on the same system id has its own ``time_boot_ms``
    and would fake reboots.
    """

    def __init__(
        self,
        system_id: int,
        origin: GeoOrigin,
        *,
        battery_low_pct: float = 25.0,
        battery_low_v: float | None = None,
        battery_hysteresis_pct: float = 5.0,
        reboot_backstep_ms: int = 3000,
        reboot_frames: int = 3,
        reboot_span_s: float = 1.0,
        statustext_timeout_s: float = 2.0,
        component_id: int | None = 1,
    ) -> None:
        self.system_id = system_id
        self.component_id = component_id
        self.origin = origin
        self.battery_low_pct = battery_low_pct
        self.battery_low_v = battery_low_v
        self.battery_hysteresis_pct = battery_hysteresis_pct
        self.reboot_backstep_ms = reboot_backstep_ms
        self.statustext_timeout_s = statustext_timeout_s
        self._snap = VehicleSnapshot(system_id=system_id)
        self._battery_low_reported = False
        self._last_position_boot_ms: int | None = None
        self._chunks: dict[int, tuple[float, int, dict[int, str], int | None]] = {}
        self.stale_messages = 0
        self.messages = 0
        self.foreign_messages = 0
        self.radio_messages = 0
        self.reboot = RebootEvidence(reboot_backstep_ms, reboot_frames, reboot_span_s)
        self._boot_verdict = "ok"
        """The reboot rule's verdict on the current frame's ``time_boot_ms``."""
        self.wind = WindEvidence()
        self.bad_wind = 0
        """WIND messages refused (non-finite or absurd values), counted and dropped."""

    def snapshot(self) -> VehicleSnapshot:
        """The current state (immutable)."""
        return self._snap

    def link_status(
        self, now_s: float, lost_after_s: float, degraded_after_s: float | None = None
    ) -> Literal["ok", "degraded", "lost"]:
        """``"ok"`` if heard within ``degraded_after_s`` (default min(2.5 s, lost/2): ~1 Hz
        telemetry with two messages missed), ``"degraded"`` until ``lost_after_s``, then
        ``"lost"`` (also before the first message)."""
        last = self._snap.last_heard_s
        if last is None:
            return "lost"
        degraded = min(2.5, lost_after_s / 2.0) if degraded_after_s is None else degraded_after_s
        silence_s = now_s - last
        if silence_s > lost_after_s:
            return "lost"
        return "degraded" if silence_s > degraded else "ok"

    def tick(self, now_s: float) -> list[TelemetryEvent]:
        """Flush incomplete STATUSTEXTs that timed out (call now and then)."""
        return self._flush_statustext(now_s)

    def receive(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        """Fold one message into the state; returns the events it caused. Never raises."""
        try:
            if msg.get_srcSystem() != self.system_id:
                return []
            if msg.get_type() in RADIO_MESSAGES:  # the radio's, whatever ids it claims
                self.radio_messages += 1
                return []
            if self.component_id is not None and msg.get_srcComponent() != self.component_id:
                self.foreign_messages += 1
                return []
        except AttributeError:
            return []
        kind = msg.get_type()
        if kind == "HEARTBEAT" and (
            getattr(msg, "autopilot", None) == mavlink2.MAV_AUTOPILOT_INVALID
            or getattr(msg, "type", None) == mavlink2.MAV_TYPE_GCS
        ):
            return []
        self.messages += 1
        self._snap = _evolve(self._snap, last_heard_s=now_s)
        events: list[TelemetryEvent] = self._flush_statustext(now_s)
        boot_ms = getattr(msg, "time_boot_ms", None)
        self._boot_verdict = "ok"
        if isinstance(boot_ms, int) and not isinstance(boot_ms, bool):
            events += self._on_boot_time(boot_ms, now_s)
        handler = _HANDLERS.get(kind)
        if handler is not None:
            try:
                events += handler(self, msg, now_s)
            except (AttributeError, TypeError, ValueError, OverflowError) as exc:
                events.append(InvalidTelemetry(now_s, kind, "<message>", repr(exc)))
        return events

    # -- helpers --------------------------------------------------------------------------

    def _on_boot_time(self, boot_ms: int, now_s: float) -> list[TelemetryEvent]:
        last = self._snap.time_boot_ms
        verdict = self.reboot.observe(last, boot_ms, now_s)
        self._boot_verdict = verdict
        if verdict == "reboot":
            return self._rebooted(boot_ms, now_s)
        changes: dict[str, object] = {"reboot_suspected": self.reboot.suspected}
        if verdict in ("ok", "resync") and (last is None or boot_ms > last):
            changes["time_boot_ms"] = boot_ms
        self._snap = _evolve(self._snap, **changes)
        return []

    def _rebooted(self, boot_ms: int, now_s: float) -> list[TelemetryEvent]:
        last = self._snap.time_boot_ms or 0
        self._snap = _evolve(
            self._snap,
            time_boot_ms=boot_ms,
            mission_current_seq=None,
            mission_total=None,
            mission_state=None,
            armed=None,
            mode=None,
            mode_name=None,
            landed_state=None,
            reboot_suspected=False,
            wind_xy_m_s=None,
            gps_fix=None,
            last_gps_s=None,
            home=None,
            home_xy_m=None,
            position_boot_ms=None,
        )
        self._last_position_boot_ms = None
        self.wind.reset()  # the autopilot's wind estimate starts again too
        return [Rebooted(now_s, last, boot_ms)]

    def _on_heartbeat(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        events: list[TelemetryEvent] = []
        status = int(msg.system_status)
        initialising = int(msg.custom_mode) == ArduPlaneMode.INITIALISING
        booting = status == MAV_STATE_BOOT or (
            int(msg.base_mode) & _CUSTOM_MODE_FLAG and initialising
        )
        if booting and self.reboot.suspected:
            latest = self.reboot.latest_ms()
            self.reboot.booting()
            events += self._rebooted(latest if latest is not None else 0, now_s)
        snap = self._snap
        armed = bool(int(msg.base_mode) & _ARMED_FLAG)
        if snap.armed is not None and armed != snap.armed:  # transitions only
            events.append(Armed(now_s) if armed else Disarmed(now_s))
        changes: dict[str, object] = {"last_heartbeat_s": now_s, "system_status": status,
                                      "armed": armed}
        if int(msg.base_mode) & _CUSTOM_MODE_FLAG:
            mode = int(msg.custom_mode)
            if mode != snap.mode:
                events.append(ModeChanged(now_s, snap.mode, mode, snap.mode_name, mode_name(mode)))
            changes.update(mode=mode, mode_name=mode_name(mode))
        self._snap = _evolve(snap, **changes)
        return events

    def _on_global_position(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        events: list[TelemetryEvent] = []
        boot_ms = int(msg.time_boot_ms)
        if self._last_position_boot_ms is not None and boot_ms < self._last_position_boot_ms:
            self.stale_messages += 1
            return events
        if self._boot_verdict != "ahead":  # a held-back boot time orders nothing
            self._last_position_boot_ms = boot_ms
        lat, lon = int(msg.lat), int(msg.lon)
        changes: dict[str, object] = {}
        if lat == 0 and lon == 0:
            pass  # no GPS fix yet: ArduPilot sends 0/0; not an error, nothing to store
        elif abs(lat) > 900_000_000 or abs(lon) > 1_800_000_000:
            events.append(InvalidTelemetry(now_s, "GLOBAL_POSITION_INT", "lat/lon", (lat, lon)))
        else:
            x_m, y_m, _ = self.origin.to_local(lat * 1e-7, lon * 1e-7)
            changes.update(x_m=x_m, y_m=y_m, last_position_s=now_s, position_boot_ms=boot_ms)
        alt_m = int(msg.relative_alt) / 1000.0
        if abs(alt_m) > _MAX_ALT_M:
            events.append(InvalidTelemetry(now_s, "GLOBAL_POSITION_INT", "relative_alt", alt_m))
        else:
            changes["alt_m"] = alt_m
        vn_m_s, ve_m_s = int(msg.vx) / 100.0, int(msg.vy) / 100.0
        changes.update(ve_m_s=ve_m_s, vn_m_s=vn_m_s, speed_m_s=math.hypot(ve_m_s, vn_m_s))
        hdg = int(msg.hdg)
        if hdg != _UINT16_UNKNOWN:
            if 0 <= hdg <= 36000:
                changes["heading_rad"] = enu_rad_from_compass_deg(hdg / 100.0)
            else:
                events.append(InvalidTelemetry(now_s, "GLOBAL_POSITION_INT", "hdg", hdg))
        self._snap = _evolve(self._snap, **changes)
        return events

    def _on_vfr_hud(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        events: list[TelemetryEvent] = []
        speeds: dict[str, float] = {}
        for name in ("groundspeed", "airspeed"):
            value = float(getattr(msg, name))
            if math.isfinite(value) and -1.0 <= value <= _MAX_SPEED_M_S:
                speeds[name] = max(value, 0.0)
            else:
                events.append(InvalidTelemetry(now_s, "VFR_HUD", name, value))
        changes: dict[str, object] = {}
        if "groundspeed" in speeds:
            changes["speed_m_s"] = speeds["groundspeed"]
        if "airspeed" in speeds:
            changes["airspeed_m_s"] = speeds["airspeed"]
        heading = int(msg.heading)
        if 0 <= heading <= 360:
            changes["heading_rad"] = enu_rad_from_compass_deg(float(heading))
        else:
            events.append(InvalidTelemetry(now_s, "VFR_HUD", "heading", heading))
        self._snap = _evolve(self._snap, **changes)
        return events

    def _on_attitude(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        yaw = float(msg.yaw)
        if not (math.isfinite(yaw) and abs(yaw) <= 2.0 * math.pi + 1e-3):
            return [InvalidTelemetry(now_s, "ATTITUDE", "yaw", yaw)]
        self._snap = _evolve(self._snap, heading_rad=wrap_pi(math.pi / 2.0 - yaw))
        return []

    def _on_sys_status(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        events: list[TelemetryEvent] = []
        present = int(msg.onboard_control_sensors_present)
        enabled = int(msg.onboard_control_sensors_enabled)
        health = int(msg.onboard_control_sensors_health)
        self._snap = _evolve(self._snap, sensors=(present, enabled, health))
        if present & PREARM_CHECK_BIT:
            ok = bool(health & PREARM_CHECK_BIT)
            if ok != self._snap.prearm_ok:
                events.append(PrearmChanged(now_s, ok))
            self._snap = _evolve(self._snap, prearm_ok=ok)
        voltage_mv = int(msg.voltage_battery)
        events += self._battery(
            now_s,
            "SYS_STATUS",
            int(msg.battery_remaining),
            None if voltage_mv == _UINT16_UNKNOWN else voltage_mv,
            int(msg.current_battery),
        )
        return events

    def _on_battery_status(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        voltages = list(msg.voltages)
        cell0 = int(voltages[0]) if voltages else _UINT16_UNKNOWN
        voltage_mv = None if cell0 == _UINT16_UNKNOWN else cell0
        return self._battery(now_s, "BATTERY_STATUS", int(msg.battery_remaining), voltage_mv,
                             int(msg.current_battery))

    def _battery(
        self, now_s: float, kind: str, remaining: int, voltage_mv: int | None,
        current_ca: int = -1,
    ) -> list[TelemetryEvent]:
        events: list[TelemetryEvent] = []
        changes: dict[str, object] = {}
        if current_ca == -1:  # ArduPilot: no current sensor / not known
            changes["battery_current_a"] = None
        elif abs(current_ca) <= _MAX_CURRENT_CA:
            changes["battery_current_a"] = current_ca / 100.0
        else:
            events.append(InvalidTelemetry(now_s, kind, "current_battery", current_ca))
        if remaining != -1:
            if 0 <= remaining <= 100:
                changes["battery_remaining_pct"] = float(remaining)
            else:
                events.append(InvalidTelemetry(now_s, kind, "battery_remaining", remaining))
        if voltage_mv is not None:
            if 0 <= voltage_mv <= 100_000:
                changes["battery_voltage_v"] = voltage_mv / 1000.0
            else:
                events.append(InvalidTelemetry(now_s, kind, "voltage", voltage_mv))
        snap = self._snap = _evolve(self._snap, **changes)
        pct, volts = snap.battery_remaining_pct, snap.battery_voltage_v
        low = (pct is not None and pct < self.battery_low_pct) or (
            self.battery_low_v is not None and volts is not None and 0 < volts < self.battery_low_v
        )
        if low and not self._battery_low_reported:
            self._battery_low_reported = True
            events.append(BatteryBelowThreshold(now_s, pct, volts, self.battery_low_pct))
        elif (
            not low
            and self._battery_low_reported
            and (pct is None or pct >= self.battery_low_pct + self.battery_hysteresis_pct)
        ):
            self._battery_low_reported = False
        return events

    def _on_mission_current(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        seq = int(msg.seq)
        total_raw = int(getattr(msg, "total", 0) or 0)
        total = None if total_raw in (0, _UINT16_UNKNOWN) else total_raw
        state_raw = int(getattr(msg, "mission_state", 0) or 0)
        state = state_raw if 0 < state_raw <= _MISSION_STATE_MAX else None
        old = self._snap.mission_current_seq
        self._snap = _evolve(
            self._snap, mission_current_seq=seq, mission_total=total, mission_state=state
        )
        if seq != old:
            return [MissionCurrentChanged(now_s, old, seq, total)]
        return []

    def _on_home_position(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        """HOME_POSITION: where the autopilot's RTL goes (lat/lon degE7, altitude mm AMSL)."""
        lat, lon, alt_mm = int(msg.latitude), int(msg.longitude), int(msg.altitude)
        if abs(lat) > 900_000_000 or abs(lon) > 1_800_000_000 or (lat == 0 and lon == 0):
            return [InvalidTelemetry(now_s, "HOME_POSITION", "lat/lon", (lat, lon))]
        if abs(alt_mm) / 1000.0 > _MAX_ALT_M:
            return [InvalidTelemetry(now_s, "HOME_POSITION", "altitude", alt_mm)]
        lat_deg, lon_deg = lat * 1e-7, lon * 1e-7
        x_m, y_m, _ = self.origin.to_local(lat_deg, lon_deg)
        self._snap = _evolve(self._snap, home=(lat_deg, lon_deg, alt_mm / 1000.0),
                             home_xy_m=(x_m, y_m), last_home_s=now_s)
        return []

    def _on_extended_sys_state(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        landed = int(msg.landed_state)
        if not 0 <= landed <= 4:
            return [InvalidTelemetry(now_s, "EXTENDED_SYS_STATE", "landed_state", landed)]
        # MAV_LANDED_STATE_UNDEFINED (0): the autopilot does not know; keep None
        self._snap = _evolve(self._snap, landed_state=landed or None)
        return []

    def _on_wind(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        wind = parse_wind_message(msg)
        if isinstance(wind, BadWindField):
            self.bad_wind += 1
            return [InvalidTelemetry(now_s, "WIND", wind.field, wind.value)]
        accepted = self.wind.observe(wind.wx_m_s, wind.wy_m_s, now_s)
        if accepted is None:
            return []
        self._snap = _evolve(self._snap, wind_xy_m_s=accepted, last_wind_s=now_s)
        return [WindReported(now_s, accepted[0], accepted[1], wind.speed_z_m_s)]

    def _on_gps_raw_int(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        """GPS_RAW_INT: the fix type, satellites and HDOP (:func:`parse_gps_raw_int`); a
        field that is garbage is stored as unknown and reported."""
        fix = parse_gps_raw_int(msg)
        self._snap = _evolve(self._snap, gps_fix=fix, last_gps_s=now_s)
        return [InvalidTelemetry(now_s, "GPS_RAW_INT", b.field, b.value) for b in fix.bad]

    def _on_item_reached(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        return [MissionItemReached(now_s, int(msg.seq))]

    def _on_statustext(self, msg: MAVLinkMessage, now_s: float) -> list[TelemetryEvent]:
        raw = msg.text
        text = raw.decode("utf-8", "replace") if isinstance(raw, bytes | bytearray) else str(raw)
        text = text.split("\x00", 1)[0]
        severity = int(msg.severity)
        text_id = int(getattr(msg, "id", 0) or 0)
        if text_id == 0:
            return [StatusText(now_s, severity, text)]
        chunk_seq = int(getattr(msg, "chunk_seq", 0) or 0)
        first_s, _, chunks, last_seq = self._chunks.get(text_id, (now_s, severity, {}, None))
        chunks[chunk_seq] = text
        if len(text) < _STATUSTEXT_CHUNK:
            last_seq = chunk_seq  # a short chunk ends the text
        self._chunks[text_id] = (first_s, severity, chunks, last_seq)
        if last_seq is not None and all(i in chunks for i in range(last_seq + 1)):
            del self._chunks[text_id]
            return [StatusText(now_s, severity, "".join(chunks[i] for i in range(last_seq + 1)))]
        return []

    def _flush_statustext(self, now_s: float) -> list[TelemetryEvent]:
        events: list[TelemetryEvent] = []
        for text_id, (first_s, severity, chunks, _) in list(self._chunks.items()):
            if now_s - first_s >= self.statustext_timeout_s:
                del self._chunks[text_id]
                top = max(chunks)
                text = "".join(chunks.get(i, "[...]") for i in range(top + 1))
                gapless = all(i in chunks for i in range(top + 1))  # unterminated 50k text
                events.append(StatusText(now_s, severity, text, complete=gapless))
        return events


_HANDLERS = {
    "HEARTBEAT": VehicleTelemetry._on_heartbeat,
    "GLOBAL_POSITION_INT": VehicleTelemetry._on_global_position,
    "VFR_HUD": VehicleTelemetry._on_vfr_hud,
    "ATTITUDE": VehicleTelemetry._on_attitude,
    "SYS_STATUS": VehicleTelemetry._on_sys_status,
    "BATTERY_STATUS": VehicleTelemetry._on_battery_status,
    "MISSION_CURRENT": VehicleTelemetry._on_mission_current,
    "MISSION_ITEM_REACHED": VehicleTelemetry._on_item_reached,
    "STATUSTEXT": VehicleTelemetry._on_statustext,
    "EXTENDED_SYS_STATE": VehicleTelemetry._on_extended_sys_state,
    "HOME_POSITION": VehicleTelemetry._on_home_position,
    "WIND": VehicleTelemetry._on_wind,
    "GPS_RAW_INT": VehicleTelemetry._on_gps_raw_int,
}


# --------------------------------------------------------------------------- loiter end


class LoiterEndDetector:
    """Detects, once, the end of the timed loiter at mission item ``loiter_seq``.

    ArduPlane sends MISSION_ITEM_REACHED for it only once, so on a lossy link the end is
    also inferred from MISSION_CURRENT moving past it: after a MISSION_CURRENT <= N has been
    seen, any MISSION_CURRENT > N (or a MISSION_ITEM_REACHED > N) ends it. MISSION_CURRENT
    values > N seen *before* that are ignored: they are the previous mission's (after a
    re-upload the plane keeps flying its old item, MISSION_CURRENT may even exceed the
    total). Feed it the reducer's events; :meth:`feed` returns True exactly once.
    """

    def __init__(self, loiter_seq: int, *, current_seq: int | None = None) -> None:
        """``current_seq``: the vehicle's MISSION_CURRENT when the detector is created
        (from the snapshot), since the reducer reports only changes."""
        self.loiter_seq = loiter_seq
        self.ended = False
        self.ended_by: str | None = None
        self.ended_at_s: float | None = None
        self._seen_at_or_before = current_seq is not None and current_seq <= loiter_seq

    def feed(self, event: TelemetryEvent) -> bool:
        """Update with one event; True if this event is the one that ends the loiter."""
        if self.ended:
            return False
        if isinstance(event, Rebooted):
            self._seen_at_or_before = False
            return False
        if isinstance(event, MissionItemReached):
            if event.seq == self.loiter_seq or (
                event.seq > self.loiter_seq and self._seen_at_or_before
            ):
                return self._end("reached", event.t_s)
            return False
        if isinstance(event, MissionCurrentChanged):
            if event.seq <= self.loiter_seq:
                self._seen_at_or_before = True
            elif self._seen_at_or_before:
                return self._end("mission_current", event.t_s)
        return False

    def _end(self, how: str, t_s: float) -> bool:
        self.ended, self.ended_by, self.ended_at_s = True, how, t_s
        return True
