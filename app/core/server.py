"""How ``backlash serve`` runs the application under uvicorn: who may be served, and how long a client may dawdle.

* :func:`check_exposure`: a service bound to an address other than loopback must have an API key,
  unless ``BACKLASH_ALLOW_NO_KEY`` says every client on that network is trusted.
* :func:`uvicorn_config`: uvicorn's keep-alive timeout and header-size limit, and a read timeout
  uvicorn does not have: a connection that has not sent a complete request head within
  ``BACKLASH_READ_TIMEOUT`` seconds of its opening (or of the previous answer) is closed
  (:class:`HeadTimeoutProtocol`). The same timeout between two pieces of a body is the application's
  (:class:`app.api.middleware.BodyReadTimeoutMiddleware`, 408).
"""

from __future__ import annotations

import asyncio
import ipaddress
import logging
import socket
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

from app.core.config import Settings

logger = logging.getLogger(__name__)

__all__ = ["HEADER_BYTES", "ExposureError", "HeadTimeoutProtocol", "check_exposure", "is_loopback", "uvicorn_config"]

#: Largest request head (request line and headers) [bytes]; h11 answers 431 beyond (uvicorn's default, stated).
HEADER_BYTES = 16 * 1024


class ExposureError(RuntimeError):
    """The service would serve a network without an API key; the message says what to set."""


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address or a name) means this machine only: every address it resolves to is loopback.

    A name that does not resolve counts as not loopback.
    """
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, None)
    except OSError:
        return False
    addresses = {info[4][0] for info in infos}
    return bool(addresses) and all(ipaddress.ip_address(str(a).split("%")[0]).is_loopback for a in addresses)


def check_exposure(settings: Settings, host: str) -> None:
    """Refuse to serve on ``host`` when it is not loopback and the service has no API key.

    Raises
    ------
    ExposureError
        ``host`` is reachable from other machines, ``BACKLASH_API_KEY`` is unset and ``BACKLASH_ALLOW_NO_KEY``
        is not set.
    """
    if settings.api_key is not None or is_loopback(host):
        return
    if settings.allow_no_key:
        logger.warning("serving %s without an API key (BACKLASH_ALLOW_NO_KEY): every client there is trusted", host)
        return
    raise ExposureError(
        f"refusing to serve on {host}, which other machines can reach, without an API key: set BACKLASH_API_KEY "
        "(clients then send it in the X-API-Key header), or BACKLASH_ALLOW_NO_KEY=1 if every client on that "
        "network is trusted, or listen on 127.0.0.1"
    )


class HeadTimeoutProtocol(H11Protocol):
    """uvicorn's h11 protocol, closing a connection whose request head is not complete within :attr:`head_timeout`.

    The clock starts when the connection opens, and when the first bytes of a later request's head arrive
    (uvicorn's keep-alive timeout closes a connection idle after an answer). A connection that sent nothing is
    closed silently; one that sent part of a head is answered 408 first.
    """

    #: Seconds a request head may take (set by :func:`uvicorn_config` on a subclass).
    head_timeout: float = 30.0

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self._head_timer: asyncio.TimerHandle | None = None
        self._head_started = False
        super().connection_made(transport)  # type: ignore[arg-type]
        self._start_head_timer()

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        if self._awaiting_head():
            self._head_started = True
            self._start_head_timer()
        else:
            self._stop_head_timer()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        self._stop_head_timer()  # an idle connection is the keep-alive timeout's
        self._head_started = False

    def connection_lost(self, exc: Exception | None) -> None:
        self._stop_head_timer()
        super().connection_lost(exc)

    def _awaiting_head(self) -> bool:
        return self.conn.their_state is h11.IDLE and not self.transport.is_closing()

    def _start_head_timer(self) -> None:
        if self._head_timer is None:
            self._head_timer = self.loop.call_later(self.head_timeout, self._head_timed_out)

    def _stop_head_timer(self) -> None:
        if self._head_timer is not None:
            self._head_timer.cancel()
            self._head_timer = None

    def _head_timed_out(self) -> None:
        self._head_timer = None
        if not self._awaiting_head():
            return
        if self._head_started and (self.cycle is None or self.cycle.response_complete):
            self.transport.write(_HEAD_TIMEOUT_ANSWER)  # nothing of ours is on the wire: say why
        self.transport.close()


def _head_timeout_answer() -> bytes:
    body = b"the request head (request line and headers) did not arrive in time\n"
    head = (
        b"HTTP/1.1 408 Request Timeout\r\ncontent-type: text/plain; charset=utf-8\r\nconnection: close\r\n"
        + f"content-length: {len(body)}\r\n\r\n".encode()
    )
    return head + body


_HEAD_TIMEOUT_ANSWER = _head_timeout_answer()


def uvicorn_config(settings: Settings) -> dict[str, Any]:
    """uvicorn's keyword arguments for the service's timeouts and limits (``uvicorn.run(app, **these, ...)``)."""
    protocol = type("ServiceH11Protocol", (HeadTimeoutProtocol,), {"head_timeout": float(settings.read_timeout)})
    return {
        "http": protocol,
        "timeout_keep_alive": settings.keep_alive_timeout,
        "h11_max_incomplete_event_size": HEADER_BYTES,
    }
