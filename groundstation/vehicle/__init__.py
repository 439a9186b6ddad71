"""One vehicle's policy as a sans-IO controller (no I/O, no clock, no asyncio).

:mod:`.controller` decides; :mod:`.evidence` holds the rules that make one frame unable to
change a vehicle's fate; :mod:`.io` the typed inputs and outputs; :mod:`.modes` ArduPlane's
modes; :mod:`.settings` the controller's settings. The daemon's session drives it.
"""
