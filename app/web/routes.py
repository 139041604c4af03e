"""Routes of the report page: ``/`` (the page) and ``/static/*`` (its script and style sheet).

The page is one server-rendered template; everything it shows comes from the JSON API
(``/v1/...``), which its script calls with ``fetch()``, sending the API key the user typed
when the service has one. The figures are PNGs rendered on the server by the engine's
matplotlib plots (``GET /v1/diagnoses/{id}/figures/{name}``,
``GET /v1/assets/{asset}/trend/figure``), so the page, the CLI and the documentation show
the same figures and no charting library is shipped to the browser.

None of these routes appear in the OpenAPI schema.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates

from app.api.routes.health import package_version
from app.core.config import API_V1_STR
from engine.constants import CHANNEL_UNITS, CHANNELS, MODEL_VERSION

__all__ = ["STATIC_DIR", "TEMPLATE_DIR", "router"]

#: Folder of the page's templates.
TEMPLATE_DIR = Path(__file__).parent / "templates"
#: Folder of the page's script and style sheet, served at ``/static``.
STATIC_DIR = Path(__file__).parent / "static"

templates = Jinja2Templates(directory=TEMPLATE_DIR)

router = APIRouter(include_in_schema=False)
router.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")


@router.get("/", response_class=HTMLResponse, include_in_schema=False)
def report_page(request: Request) -> HTMLResponse:
    """The report page.

    Parameters
    ----------
    request : Request
        The request (the template reads the application's settings from it).

    Returns
    -------
    HTMLResponse
        The page; it asks for the API key only when the service has one.
    """
    settings = request.app.state.settings
    context = {
        "api_prefix": API_V1_STR,
        "api_key_required": settings.api_key is not None,
        "channels": [(c, CHANNEL_UNITS[c]) for c in CHANNELS],
        "version": package_version(),
        "model_version": MODEL_VERSION,
    }
    return templates.TemplateResponse(request, "report.html", context)
