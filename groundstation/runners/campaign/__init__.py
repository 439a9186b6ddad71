"""``gcs campaign``: many offline simulations over a grid, results stored as they finish,
and ``gcs campaign report`` (docs/campaigns.md).

Running: :mod:`.grid` (the campaign file), :mod:`.driver` (the one writer), :mod:`.store`
(the results folder, :mod:`.schema` its columns), :mod:`.run` (one run in a worker),
executors :mod:`.pool` (a local process pool) and :mod:`.dask` (imported only for
``--dask``), :mod:`.summary` (the end-of-run table). Reporting: :mod:`.data`,
:mod:`.stats`, :mod:`.paired`, :mod:`.table`, :mod:`.plots` and :mod:`.report` (the page).
"""
