"""``gcs replay``: a recorded run through today's decision core, and tlogs served back.

:mod:`.run` replays a journal decision by decision (``replay_journal``), comparing with
:mod:`.compare`; :mod:`.journal` reads journals robustly (replay and reports);
:mod:`.tlog` what a tlog holds per vehicle; :mod:`.tlog_core` the core on a bare tlog plus
detections; :mod:`.serve` and :mod:`.mission_timeline` the schedule for serving a tlog as
live MAVLink.
"""
