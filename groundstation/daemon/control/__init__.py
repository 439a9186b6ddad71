"""The daemon's control surface, one HTTP subsystem (docs/control.md).

:mod:`.server` is the aiohttp server (JSON API, WebSocket, the live page in ``web/``); it
only calls the :class:`~.contract.DaemonControl` contract (:mod:`.contract`), which the
daemon implements in :mod:`.controller`. Beneath the server: who may talk to it and how much
(:mod:`.guard`), request bodies and JSON replies (:mod:`.bodies`), the live pages'
WebSocket fan-out (:mod:`.push`) and what it keeps per page (:mod:`.pages`). Importing this
package imports none of them.
"""
