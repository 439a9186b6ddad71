"""``--vehicles sim:N``: the built-in simulator in the daemon's own event loop.

This adapter lives in the command layer so that the daemon never imports the simulator:
``gcs run`` hands the daemon :func:`build_embedded_sim` as its
:data:`~groundstation.daemon.embedded.EmbeddedFactory`.

The vehicles serve TCP on ephemeral 127.0.0.1 ports and the daemon connects to them with
ordinary ``tcp:`` links, exactly as to ArduPilot SITL. Launch poses, origin and home come
from the scenario (``sitl.sitl_setup.scenario_setup``), whose scripted vehicle events
become simulator faults (vehicle_lost -> link drop, override -> the operator switches to
FBWA, resume -> AUTO, battery_low -> 10 %); ``sim.faults`` and ``sim.loss`` add more (one
builder, :func:`sitl.faults.fault_specs`). Links go through simulated SiK radios as the
scenario's ``radio:`` and then ``sim.radio`` (``--sim-radio``) say (:mod:`sitl.radio`;
:meth:`EmbeddedSim.radio_stats` gives their figures). The vehicles fly in
``WindField(wind, config.mission.seed)`` (the seed the daemon's world draws the icebergs
with): ``wind`` as given, else the scenario's, else calm. The
mission clock follows the simulator's simulated time. The simulator ticks every 5 ms and
advances by at most max(0.05 s, min(0.5 s, 5 ms x K)) per tick, so a loaded host slows the
run down instead of making the vehicles' clocks jump (a jump of a few simulated seconds
fires ArduPlane's 1 s re-request and 8 s upload timers for nothing).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from domain.errors import ConfigError
from domain.geodesy import GeoOrigin
from domain.radio_spec import RadioSpecError, radio_assignments
from groundstation.commands.sitl_args import DEFAULT_HOME
from groundstation.daemon.config import DaemonConfig, controller_settings
from sitl.faults import FaultError, build_faults, fault_specs
from sitl.server import ServerOptions, SitlServer
from sitl.sitl_setup import scenario_setup
from world.scenario import Scenario
from world.wind import WindSpec

__all__ = ["EmbeddedSim", "build_embedded_sim"]

SIM_TICK_S = 0.005


@dataclass
class EmbeddedSim:
    """The built-in vehicles as the daemon's :class:`EmbeddedVehicles`."""

    server: SitlServer
    origin: GeoOrigin
    fault_specs: list[str]
    wind: WindSpec = field(default_factory=WindSpec)
    """The wind the vehicles fly in (``gcs run --wind``, else the scenario's)."""

    def now_s(self) -> float:
        return self.server.t_s

    def radio_stats(self) -> dict[int, dict[str, Any]]:
        """Each radio link's figures by system id (none without radios)."""
        return self.server.radio_stats()

    def link_urls(self) -> list[str]:
        return [f"tcp:127.0.0.1:{port}" for port in self.server.tcp_ports]

    def airborne_positions(self) -> dict[int, tuple[float, float]]:
        return {
            v.system_id: (v.airframe.x_m, v.airframe.y_m)
            for v in self.server.vehicles()
            if not v.airframe.on_ground
        }

    async def start(self) -> None:
        await self.server.start()

    async def run(self) -> None:
        await self.server.run()

    def stop(self) -> None:
        self.server.stop()

    async def close(self) -> None:
        await self.server.close()


def build_embedded_sim(
    config: DaemonConfig,
    scenario: Scenario | None,
    signing_keys: dict[int, bytes] | None = None,
    wind: WindSpec | None = None,
) -> EmbeddedSim:
    """The simulator for ``config.sim_count`` vehicles (not started); ``signing_keys``:
    the MAVLink 2 signing key each system id starts with; ``wind``: the wind they fly in
    (None: the scenario's, calm without one)."""
    count = config.sim_count
    assert count is not None
    origin = config.mission.origin
    home = DEFAULT_HOME if origin is None else (origin.lat_deg, origin.lon_deg)
    setup = scenario_setup(scenario, count, home, origin is not None)
    configs = []
    start_unix_s = time.time()
    for i in range(count):
        # airborne vehicles start at the altitude the controller will command them to
        alt = controller_settings(config, config.settings_for(i + 1), i).altitude_m
        configs.append(setup.vehicle_config(
            i, airborne=config.sim.airborne, airborne_alt_m=alt,
            fast_boot=config.sim.fast_boot, unix_time_at_zero_s=start_unix_s,
            wind=wind, wind_seed=config.mission.seed,
        ))
    specs = fault_specs(
        config.sim.faults, loss=config.sim.loss or None, scripted=setup.fault_specs
    )
    try:
        faults = build_faults(specs, [c.system_id for c in configs], config.mission.seed)
    except FaultError as exc:
        raise ConfigError(f"sim_fault: {exc}") from None

    try:
        radios = radio_assignments([*setup.radio_specs, *config.sim.radio],
                                   [c.system_id for c in configs])
    except RadioSpecError as exc:
        raise ConfigError(f"sim_radio: {exc}") from None

    speedup = config.speedup_x
    # The simulated clock is the daemon's mission clock: one tick must never move it more
    # than 0.5 s (ArduPlane answers within a 20 ms loop; a transfer times out after 1.5 s).
    # Above 100x the tick gets shorter instead of longer: at 200x, 5 ms ticks of 1 s made
    # every round trip look like 1-2 s to the daemon (12 of 12 target uploads failed).
    step_s = max(0.05, min(0.5, speedup * SIM_TICK_S))
    tick_s = min(SIM_TICK_S, step_s / speedup)
    options = ServerOptions(
        speedup=speedup,
        host="127.0.0.1",
        base_port=0,
        tick_s=tick_s,
        max_step_s=step_s,
        max_stall_s=tick_s,
        signing_keys=dict(signing_keys or {}),
        radios=radios,
        radio_seed=config.mission.seed,
    )
    flown = wind if wind is not None else scenario.wind if scenario is not None else WindSpec()
    return EmbeddedSim(SitlServer(configs, options, faults, None), setup.origin, specs, flown)
