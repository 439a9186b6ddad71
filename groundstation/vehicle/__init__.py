"""One vehicle's policy as a sans-IO controller (no I/O, no clock, no asyncio).

:mod:`.controller` decides (its state in :mod:`.state`); :mod:`.evidence` holds the rules
that make one frame unable to change a vehicle's fate and :mod:`.watch` applies them;
:mod:`.jobs` the multi-step exchanges; :mod:`.io` the typed inputs and outputs;
:mod:`.modes` ArduPlane's modes; :mod:`.settings` the controller's settings. The daemon's
session drives it.
"""
