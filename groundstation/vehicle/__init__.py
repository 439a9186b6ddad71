"""One vehicle's policy as a sans-IO controller (no I/O, no clock, no asyncio).

:mod:`.controller` decides (its states and the link's: :mod:`.state`); :mod:`.watch`
applies the rules that make one frame unable to change a vehicle's fate
(``groundstation.mavlink.evidence``); :mod:`.jobs` the multi-step exchanges;
:mod:`.controller_io` the typed inputs and outputs; :mod:`.settings` the controller's
settings (ArduPlane's modes: ``domain.modes``). The daemon's session drives it.
"""
