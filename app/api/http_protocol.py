"""The HTTP protocol ``bioplan serve`` runs: uvicorn's h11 one, with a deadline for a request's
head.

uvicorn closes a connection that stays idle after a response (``timeout_keep_alive``), but not
one that sends half a request line or half its headers and then nothing: 2000 such connections
were held open for as long as the clients liked. Here a request's head (request line and
headers) must be complete within ``head_timeout`` seconds of the connection opening or of the
previous response; otherwise the connection is closed. Bodies are not timed (a large upload on
a slow link is legitimate; their size is bounded by the body limits).
"""

from __future__ import annotations

import asyncio

from uvicorn.protocols.http.h11_impl import H11Protocol

#: Seconds a client has to send a complete request head.
DEFAULT_HEAD_TIMEOUT_S = 10.0


def head_timeout_protocol(head_timeout: float) -> type[H11Protocol]:
    """An h11 protocol class whose connections must send each request head within
    ``head_timeout`` seconds (for ``uvicorn.Config(http=...)``)."""

    class HeadTimeoutProtocol(H11Protocol):
        _head_timer: asyncio.TimerHandle | None = None

        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
            super().connection_made(transport)
            self._arm()

        def on_response_complete(self) -> None:
            super().on_response_complete()
            self._arm()

        def handle_events(self) -> None:
            super().handle_events()
            if self.cycle is not None and not self.cycle.response_complete:
                self._disarm()  # a request is being answered: its head arrived

        def connection_lost(self, exc: Exception | None) -> None:
            self._disarm()
            super().connection_lost(exc)

        def _arm(self) -> None:
            self._disarm()
            if not self.transport.is_closing():
                self._head_timer = self.loop.call_later(head_timeout, self._head_too_slow)

        def _disarm(self) -> None:
            if self._head_timer is not None:
                self._head_timer.cancel()
                self._head_timer = None

        def _head_too_slow(self) -> None:
            self._head_timer = None
            waiting = self.cycle is None or self.cycle.response_complete
            if waiting and not self.transport.is_closing():
                self.logger.info("closing a connection whose request head took over %g s",
                                 head_timeout)  # fmt: skip
                self.transport.close()

    return HeadTimeoutProtocol
