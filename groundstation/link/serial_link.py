"""Serial links (``serial:/dev/ttyUSB0:57600``, ``/dev/ttyUSB0,57600``, ``COM3,57600``).

Uses pyserial-asyncio-fast (imported only when a serial link starts). A port that vanishes
(USB radio unplugged: the read fails) or cannot be opened yet is reopened with back-off,
so plugging the radio back in restores the link; use a stable name such as
``/dev/serial/by-id/...`` so the device keeps its path.
"""

from __future__ import annotations

import asyncio
from typing import Any

from domain.errors import LinkError
from groundstation.link.stream import ReconnectingLink, StreamProtocol

__all__ = ["SerialLink"]


def _serial_module() -> Any:
    try:
        import serial_asyncio_fast
    except ImportError:
        raise LinkError(
            "serial links need the pyserial-asyncio-fast package "
            "(pip install pyserial-asyncio-fast)"
        ) from None
    return serial_asyncio_fast


class SerialLink(ReconnectingLink):
    """One serial port, 8N1, no flow control, at the URL's baud rate."""

    def _describe(self) -> str:
        return f"serial {self.spec.device} at {self.spec.baud} baud"

    async def _open(self) -> None:
        self._module = _serial_module()  # fail at start if the package is missing
        await super()._open()

    async def _connect(self) -> StreamProtocol:
        loop = asyncio.get_running_loop()
        _, proto = await self._module.create_serial_connection(
            loop, lambda: StreamProtocol(self, None), self.spec.device, baudrate=self.spec.baud
        )
        assert isinstance(proto, StreamProtocol)
        return proto
