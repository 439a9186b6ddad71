"""``gcs report``: one self-contained HTML page about a flight.

:mod:`.page` builds it (``build_report``) from :mod:`.data` (a run folder, a journal or a
bare tlog) and :mod:`.plots`; the tracker's side is :mod:`.track_data` and
:mod:`.track_plots`.
"""
