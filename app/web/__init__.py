"""The report page: a small web UI served by the service itself at ``/``.

Server-rendered (a Jinja2 template, :mod:`app.web.routes`) with one plain JavaScript file
that calls the JSON API; the figures are the engine's PNGs served by the API. Nothing is
built and nothing is loaded from outside the service.
"""

from app.web.routes import router

__all__ = ["router"]
