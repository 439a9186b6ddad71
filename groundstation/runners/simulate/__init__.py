"""``gcs simulate``: the decision core against the world model, in fixed virtual-time steps.

:mod:`.simulator` runs it (``run_simulation``); :mod:`.vehicle` is a simulated UAV flying
what the core commands; :mod:`.discovery` the unknown icebergs, the unlabelled camera and
the track-quality measures; :mod:`.plots` the PNGs of a simulated run.
"""
