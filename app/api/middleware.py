"""ASGI middleware: the optional API key, the request-body size limit and the body's read timeout."""

from __future__ import annotations

import hmac
import json

import anyio
from starlette.exceptions import HTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

API_KEY_HEADER = "X-API-Key"


async def _send_json(send: Send, status: int, body: dict, headers: list[tuple[bytes, bytes]] | None = None) -> None:
    data = json.dumps(body).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(data)).encode()),
                *(headers or []),
            ],
        }
    )
    await send({"type": "http.response.body", "body": data})


def key_matches(given: str | bytes | None, key: str | bytes) -> bool:
    """Whether ``given`` (the header's value) is the API key ``key``, compared in constant time."""
    if given is None:
        return False
    as_bytes = given.encode("latin-1", errors="replace") if isinstance(given, str) else given
    return hmac.compare_digest(as_bytes, key.encode() if isinstance(key, str) else key)


class ApiKeyMiddleware:
    """Every HTTP request but the exempt paths must carry ``X-API-Key: <key>`` (401 otherwise)."""

    def __init__(
        self,
        app: ASGIApp,
        api_key: str,
        exempt: frozenset[str] = frozenset({"/healthz", "/"}),
        exempt_prefixes: tuple[str, ...] = ("/static/",),
    ) -> None:
        """``exempt``: exact paths served without the key (health, the report page, which then asks for the key);
        ``exempt_prefixes``: path prefixes likewise (the page's script and stylesheet, which hold no data)."""
        self.app = app
        self._key = api_key.encode()
        self._exempt = exempt
        self._exempt_prefixes = exempt_prefixes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        path = scope.get("path", "")
        if scope["type"] != "http" or path in self._exempt or path.startswith(self._exempt_prefixes):
            await self.app(scope, receive, send)
            return
        given = next((v for k, v in scope["headers"] if k == API_KEY_HEADER.lower().encode()), None)
        if given is None or not key_matches(given, self._key):
            what = "missing" if given is None else "wrong"
            await _send_json(
                send,
                401,
                {
                    "detail": f"{what} API key: send the service's key in the {API_KEY_HEADER} header",
                    "error": "Unauthorized",
                },
                [(b"www-authenticate", API_KEY_HEADER.encode())],
            )
            return
        await self.app(scope, receive, send)


class BodySizeLimitMiddleware:
    """Refuse request bodies larger than ``max_body_bytes`` with 413.

    A declared ``Content-Length`` over the limit is refused before anything is read;
    a body without one (chunked) is counted while it is read, and reading past the
    limit raises a 413 ``HTTPException`` inside the application.
    """

    def __init__(self, app: ASGIApp, max_body_bytes: int) -> None:
        self.app = app
        self.max_body_bytes = max_body_bytes

    def _message(self, size: str) -> str:
        return (
            f"request body is {size}; the limit is {self.max_body_bytes} bytes (BACKLASH_MAX_BODY_BYTES): "
            "send fewer records or cases per request"
        )

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = next((v for k, v in scope["headers"] if k == b"content-length"), None)
        if declared is not None:
            try:
                length = int(declared)
            except ValueError:
                detail = f"invalid Content-Length header {declared.decode(errors='replace')!r}"
                await _send_json(send, 400, {"detail": detail, "error": "BadRequest"})
                return
            if length > self.max_body_bytes:
                await _send_json(
                    send,
                    413,
                    {"detail": self._message(f"{length} bytes"), "error": "ContentTooLarge"},
                    [(b"connection", b"close")],
                )
                return
        received = 0

        async def limited_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_body_bytes:
                    raise HTTPException(413, self._message(f"more than {self.max_body_bytes} bytes"))
            return message

        await self.app(scope, limited_receive, send)


class BodyReadTimeoutMiddleware:
    """Answer 408 (and close the connection) when a request's body stalls: more than ``timeout`` seconds pass
    between two of its pieces.

    A slow client would otherwise hold its connection and the request's task for as long as it likes
    (uvicorn has no read timeout; :class:`app.core.server.HeadTimeoutProtocol` limits the request head).
    Once the body is in, reads wait as long as they need (they then only wait for the client to go).
    """

    def __init__(self, app: ASGIApp, timeout: float) -> None:
        self.app = app
        self.timeout = float(timeout)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        body_done = False

        async def timed_receive() -> Message:
            nonlocal body_done
            if body_done:
                return await receive()
            with anyio.move_on_after(self.timeout) as waited:
                message = await receive()
            if waited.cancelled_caught:
                raise HTTPException(
                    408,
                    f"the request body stalled: nothing arrived for {self.timeout:g} s (BACKLASH_READ_TIMEOUT); "
                    "send it again",
                    headers={"Connection": "close"},
                )
            if message["type"] != "http.request" or not message.get("more_body", False):
                body_done = True
            return message

        await self.app(scope, timed_receive, send)


class HeadAsGetMiddleware:
    """Answer ``HEAD`` as ``GET`` (the server sends the head of the answer only), wherever ``GET`` is served.

    FastAPI's routes answer only the methods they name, so ``HEAD /`` (a link checker, a load balancer) got 405.
    The request keeps its method in the scope's ``"head_request"`` flag (the 405 answer says ``HEAD``).
    """

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and scope["method"] == "HEAD":
            scope = {**scope, "method": "GET", "head_request": True}  # a copy: the server still knows it is HEAD
        await self.app(scope, receive, send)
