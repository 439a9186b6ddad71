"""The offline applications, on virtual time: each ``gcs`` subcommand's machinery in its
own subpackage (docs/architecture.md).

:mod:`.simulate` (``gcs simulate``), :mod:`.replay` (``gcs replay``), :mod:`.report`
(``gcs report``) and :mod:`.campaign` (``gcs campaign``, ``gcs campaign report``).
:mod:`.html_page` stays here: both reports (a flight's and a campaign's) build on it.
A campaign runs the simulator and draws with the flight report's colours; a flight report
reads journals and tlogs as replay does. Importing a package imports none of its modules.
"""
