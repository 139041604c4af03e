"""ASGI middleware: the optional API key and the request-body size limit."""

from __future__ import annotations

import hmac
import json

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
        if given is None or not hmac.compare_digest(given, self._key):
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
