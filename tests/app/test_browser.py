"""The report page in a real browser: headless Chromium (Debian's package) driven by Playwright.

A real server (``backlash serve`` on a temporary database) serves the page; the browser uploads
records through the page's file input, waits for the diagnosis job and checks what a person
reads: the verdict in words, the figures (loaded, not broken), the ranked candidates, the width
identified and the drive's history with its trend; errors and warnings show at the top of the page, in
page terms, and no request of the page gets a server error (5xx). A full-page screenshot of the report is
written to ``out/test-artifacts/report_page.png`` (``out/`` is not versioned); on a failure the
page as it was is saved beside it and its path is printed with the error.

Needs ``/usr/bin/chromium`` (``apt-get install chromium fonts-dejavu-core``, done by
``make system-deps`` as root on Debian) and the ``playwright`` package (the ``test`` extra);
Playwright's own browser download is not used. Without them the tests skip, saying why.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import pytest
from servicekit import SMALL_TRAINING, Server, ServerFactory, train

#: Debian's Chromium, driven by Playwright (its own browser download cannot be reached in CI).
CHROMIUM = Path("/usr/bin/chromium")
#: Where the screenshots go (``out/`` is not versioned).
ARTIFACTS = Path(__file__).resolve().parents[2] / "out" / "test-artifacts"
#: Longest wait for a diagnosis job, in ms: the first job of a server also starts its worker process.
DIAGNOSIS_TIMEOUT_MS = 150_000
#: Longest wait for anything else the page does, in ms (also for ``expect``, whose own default is 5 s).
PAGE_TIMEOUT_MS = 30_000
#: Longest wait for the page's identification with the continuous width (a K refit: a few seconds on
#: an idle machine, over 30 s beside other work), in ms.
IDENTIFY_TIMEOUT_MS = 120_000
#: The unmodelled effect in the uploaded records (quick to diagnose: the record's conditions fix K, J1, c, c1).
EFFECT = {"motor_coulomb_friction": 0.02}
ASSET = "press-7"
API_KEY = "report-page-test-key"

needs_browser = pytest.mark.skipif(
    not CHROMIUM.exists(),
    reason=f"{CHROMIUM} is missing: install Debian's chromium (apt-get install chromium fonts-dejavu-core; "
    "`make system-deps` does it as root)",
)


def playwright() -> Any:
    """Playwright's sync API (the test skips when the package is missing)."""
    return pytest.importorskip(
        "playwright.sync_api", reason="playwright is not installed: pip install -e '.[test]' (the test extra)"
    )


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """Headless Chromium of the system, shared by the tests of this module."""
    playwright().expect.set_options(timeout=PAGE_TIMEOUT_MS)
    with playwright().sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=str(CHROMIUM), headless=True)
        try:
            yield chromium
        finally:
            chromium.close()


#: Viewport of the test pages (a laptop's): "above the fold" is y < its height.
VIEWPORT = {"width": 1280, "height": 900}


class PageErrors:
    """Uncaught JavaScript errors of a page (a broken script fails the test)."""

    def __init__(self, page: Any) -> None:
        self.errors: list[str] = []
        page.on("pageerror", lambda exc: self.errors.append(str(exc)))


class Responses:
    """Every HTTP answer the pages of a browser context got (status and URL), the figures' tabs included."""

    def __init__(self, context: Any) -> None:
        self.seen: list[tuple[int, str]] = []
        context.on("response", lambda r: self.seen.append((r.status, f"{r.request.method} {r.url}")))

    def server_errors(self) -> list[tuple[int, str]]:
        return [(status, what) for status, what in self.seen if status >= 500]


@contextmanager
def new_page(browser: Any, name: str, server: Server) -> Iterator[Any]:
    """A page in a fresh context; on a failure its screenshot and the server's log are attached to the error.

    Whatever the test does on a normal path, no request of the page may get a server error (5xx): the page
    would be showing the user a failure of the service, not of the record."""
    context = browser.new_context(viewport=VIEWPORT)
    context.set_default_timeout(PAGE_TIMEOUT_MS)
    responses = Responses(context)
    page = context.new_page()
    page.responses = responses  # the test may look at them too
    errors = PageErrors(page)
    try:
        yield page
        assert not errors.errors, f"JavaScript errors on the page: {errors.errors}"
        assert not responses.server_errors(), f"server errors on a normal path: {responses.server_errors()}"
    except Exception as exc:
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        shot = ARTIFACTS / f"{name}-failure.png"
        try:
            page.screenshot(path=str(shot), full_page=True)
            exc.add_note(f"screenshot of the page at the failure: {shot}")
        except Exception as shot_error:  # the browser may be gone: say so, keep the original error
            exc.add_note(f"no screenshot ({shot_error})")
        exc.add_note(f"server log (tail):\n{server.log()}")
        raise
    finally:
        context.close()


def simulate(api: httpx.Client, K: float, csv: bool = False) -> httpx.Response:
    """A simulated record of width ``K`` with :data:`EFFECT` (JSON, or CSV with its grid in headers)."""
    headers = {"Accept": "text/csv"} if csv else {}
    r = api.post("/v1/simulate", json={"K": K, "effects": EFFECT}, headers=headers)
    assert r.status_code == 200, r.text
    return r


def identify(api: httpx.Client, record: dict[str, Any], pattern_set: str, measured_at: str) -> dict[str, Any]:
    """Identify the width of ``record`` for :data:`ASSET` (stored in its history)."""
    body = {
        "record": {**record, "asset": ASSET, "measured_at": measured_at},
        "channel": "v2",
        "pattern_set": pattern_set,
    }
    r = api.post("/v1/identify", json=body)
    assert r.status_code == 200, r.text
    assert r.json()["identification_id"], r.json()
    return r.json()


def images_loaded(page: Any, selector: str) -> list[dict[str, Any]]:
    """Wait until every image under ``selector`` has loaded; their figure names and natural sizes."""
    page.wait_for_function(
        "(sel) => { const imgs = [...document.querySelectorAll(sel)];"
        " return imgs.length > 0 && imgs.every((i) => i.complete && i.naturalWidth > 0); }",
        arg=selector,
    )
    return page.eval_on_selector_all(
        selector,
        "(imgs) => imgs.map((i) => ({name: i.dataset.figure || i.id, width: i.naturalWidth, alt: i.alt}))",
    )


def in_view_at_the_top(page: Any, selector: str) -> None:
    """``selector`` is in the viewport now (the page scrolled to it) and above the fold of the page (it is
    seen without scrolling when the page opens)."""
    box = page.locator(selector).bounding_box()
    assert box is not None, f"{selector} is not displayed"
    assert 0 <= box["y"] < VIEWPORT["height"], (selector, box, "not in the viewport")
    top = box["y"] + page.evaluate("window.scrollY")
    assert top < VIEWPORT["height"] / 2, (selector, top, "below the top half of the page's first screen")


def table_rows(page: Any, selector: str) -> list[list[str]]:
    return page.eval_on_selector_all(
        f"{selector} tbody tr", "(rows) => rows.map((r) => [...r.cells].map((c) => c.textContent.trim()))"
    )


#: Script that records every text the job's stage line shows (in ``window.stagesSeen``).
WATCH_STAGES = """() => {
  window.stagesSeen = [];
  const stage = document.getElementById("job-stage");
  new MutationObserver(() => window.stagesSeen.push(stage.textContent)).observe(
    stage, {childList: true, characterData: true, subtree: true});
}"""


def wait_for_diagnosis(page: Any, previous: str | None) -> str:
    """Wait until the page shows a diagnosis other than ``previous`` with its verdict; its id."""
    page.wait_for_function(
        "(prev) => { const s = document.getElementById('report-section');"
        " return !s.hidden && s.dataset.diagnosis && s.dataset.diagnosis !== prev"
        " && document.getElementById('verdict-status'); }",
        arg=previous or "",
        timeout=DIAGNOSIS_TIMEOUT_MS,
    )
    return page.get_attribute("#report-section", "data-diagnosis")


@needs_browser
def test_report_page_diagnoses_uploaded_records(start_server: ServerFactory, browser: Any, tmp_path: Path) -> None:
    """Upload a JSON record, watch the job, read the report; identify its width; upload a CSV record of the
    same drive; the drive's history, trend and figure follow. Screenshot: out/test-artifacts/report_page.png."""
    server = start_server()
    expect = playwright().expect
    with server.client() as api:
        pattern_set = train(api, SMALL_TRAINING)
        assert pattern_set["job"]["state"] == "done", pattern_set["job"]
        set_id = pattern_set["pattern_set_id"]
        # two earlier identifications of the drive, a fortnight apart, its width growing
        for K, day in ((0.0045, "2026-10-01"), (0.005, "2026-10-15")):
            identify(api, simulate(api, K).json(), set_id, f"{day}T08:00:00Z")
        record = simulate(api, 0.0055).json()
        record["conditions"].pop("K")  # the width is what the diagnosis is to find
        csv_answer = simulate(api, 0.0055, csv=True)
        paths = api.get("/openapi.json").json()["paths"]
        assert "/" not in paths and not any(p.startswith("/static") for p in paths), sorted(paths)
        script = api.get("/static/report.js")
        assert script.status_code == 200 and "javascript" in script.headers["content-type"], script.headers
    json_file = tmp_path / "press-7-2026-11-01.json"
    json_file.write_text(json.dumps(record))
    csv_file = tmp_path / "press-7-2026-11-08.csv"
    csv_file.write_text(csv_answer.text)

    with new_page(browser, "report_page", server) as page:
        page.goto(server.base_url + "/")
        expect(page).to_have_title("Backlash diagnosis report")
        expect(page.locator("#key-form")).to_be_hidden()  # the service has no key

        # 1. upload the JSON record of the drive and diagnose it
        page.set_input_files("#record-file", str(json_file))
        page.fill("#asset", ASSET)
        page.fill("#measured-at", "2026-11-01T08:00:00Z")
        page.evaluate(WATCH_STAGES)
        page.click("#diagnose-button")
        expect(page.locator("#job-section")).to_be_visible()
        first = wait_for_diagnosis(page, None)
        assert f"diagnosis={first}" in page.url

        # the job's progress was shown while it ran, then done
        stages = page.evaluate("window.stagesSeen")
        assert any(s.startswith(("queued", "running")) for s in stages), stages
        expect(page.locator("#job-stage")).to_have_text("done (100 %)")
        assert page.get_attribute("#job-progress", "value") == "1"
        expect(page.locator("#verdict-status")).to_have_text("Explained")
        verdict = page.inner_text("#verdict-text")
        found = re.search(r"explained by motor coulomb friction = ([0-9.e+-]+) ± ([0-9.e+-]+) pu", verdict)
        assert found and float(found[1]) == pytest.approx(0.02, rel=0.02), verdict
        assert "100 % of the gap" in verdict and "at the motor shaft" in verdict, verdict
        assert "× the noise RMS with the nominal model" in verdict, verdict
        # the width shown is the named model's, with its 95 % interval, which covers the truth (issue 50)
        shown = re.search(
            r"Backlash width: ([0-9.]+) mm, 95 % interval ([0-9.]+)–([0-9.]+) mm \(from the model with motor coulomb friction\)",
            verdict,
        )
        assert shown and float(shown[2]) <= 5.5 <= float(shown[3]), verdict
        gap = table_rows(page, "#gap-table")
        assert [r[0] for r in gap] == ["before", "after"], gap

        figures = images_loaded(page, "#figures img")
        names = {f["name"] for f in figures}
        assert {"residual_map_before", "residual_map_after", "overlays", "gap_budget"} <= names, figures
        assert all(f["width"] > 100 and f["alt"] for f in figures), figures
        # every figure opens full size: a click on it opens the very PNG in a new tab at its own size
        link = page.locator('#figures a.full-size:has(img[data-figure="overlays"])')
        with page.expect_popup() as popup_info:
            link.click()
        popup = popup_info.value
        popup.wait_for_load_state()
        full = popup.evaluate("() => document.images[0].naturalWidth")
        shown_width = page.evaluate(
            "() => document.querySelector('#figures img[data-figure=\"overlays\"]').getBoundingClientRect().width"
        )
        natural = next(f["width"] for f in figures if f["name"] == "overlays")
        assert full == natural > shown_width, (full, natural, shown_width)
        popup.close()

        candidates = table_rows(page, "#candidates")
        assert len(candidates) > 5, candidates
        assert candidates[0][:2] == ["1", "motor coulomb friction"], candidates[0]
        assert float(candidates[0][2].split()[0]) == pytest.approx(0.02, rel=0.02), candidates[0]

        # the drive's history: the two identifications and this diagnosis
        expect(page.locator("#history-asset")).to_have_value(ASSET)
        expect(page.locator("#history tbody tr")).to_have_count(3)
        history = table_rows(page, "#history")
        assert [r[1] for r in history] == ["identification", "identification", "diagnosis"], history
        assert history[2][3] == "explained: motor coulomb friction", history
        expect(page.locator("#trend")).to_contain_text("No trend yet")

        # 2. identify the width of the same upload with the small pattern set: a third estimate, so a trend
        page.select_option("#pattern-set", set_id)
        page.click("#identify-button")
        expect(page.locator("#identification-text")).to_contain_text("Identified width:", timeout=IDENTIFY_TIMEOUT_MS)
        text = page.inner_text("#identification-text")
        assert "Continuous width:" in text and "Stored in the drive's history" in text, text
        expect(page.locator("#history tbody tr")).to_have_count(4)
        expect(page.locator("#trend")).to_contain_text("The width grows by")
        page.fill("#limit", "7")
        page.click("#asset-button")
        expect(page.locator("#trend")).to_contain_text("the limit of 7 mm")
        (trend_figure,) = images_loaded(page, "#trend-image")
        assert trend_figure["width"] > 100, trend_figure

        # 3. a second upload of the same drive, as CSV with its grid and known conditions as parameters
        page.set_input_files("#record-file", str(csv_file))
        page.fill("#measured-at", "2026-11-08T08:00:00Z")
        page.fill("#sample-interval", csv_answer.headers["X-Sample-Interval"])
        page.fill("#event-index", csv_answer.headers["X-Event-Index"])
        page.fill("#conditions", "J1=0.87 c=1 c1=0.2 K=0.0055")
        page.click("#diagnose-button")
        second = wait_for_diagnosis(page, first)
        expect(page.locator("#verdict-status")).to_have_text("Explained")
        images_loaded(page, "#figures img")
        expect(page.locator("#history tbody tr")).to_have_count(5)
        kinds = [r[1] for r in table_rows(page, "#history")]
        assert kinds.count("diagnosis") == 2, kinds
        expect(page.locator("#message")).to_have_text("Diagnosis done.")
        images_loaded(page, "#trend-image")

        # the stored records can be picked again
        page.click("#refresh-records")
        expect(page.locator("#stored-record option")).to_have_count(3)  # "(none)" and the two uploads
        assert second != first
        # no error and no warning on this path, and no server error on any of its requests (the page's API
        # calls, jobs polled, figures): new_page checks it again at the end
        expect(page.locator("#alerts")).to_be_empty()
        api_calls = [what for _, what in page.responses.seen if "/v1/" in what]
        assert len(api_calls) > 20, api_calls
        assert not page.responses.server_errors(), page.responses.server_errors()

        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        shot = ARTIFACTS / "report_page.png"
        page.screenshot(path=str(shot), full_page=True)
        print(f"screenshot of the report page: {shot}")
        assert shot.stat().st_size > 10_000


@needs_browser
def test_report_page_diagnoses_a_record_of_an_uploaded_fmu_plant(
    start_server: ServerFactory, browser: Any, tmp_path: Path
) -> None:
    """Issue 55: a plant uploaded as an FMU appears in the page's plant choice; its CSV record is diagnosed
    with the plant's id (no drive parameters), and the report names the effect the record was made with."""
    from fmukit import OCTET, as_csv, local_plant, small_description, synthetic

    from engine.plants.fmu import EXAMPLES_DIR
    from engine.plants.fmu.build import build_fmu

    fmu = build_fmu(EXAMPLES_DIR / "quarter_car", tmp_path / "fmu")
    server = start_server(allow_fmu_plants="1")
    expect = playwright().expect
    with server.client() as api:
        up = api.post("/v1/fmus", content=fmu.read_bytes(), headers=OCTET)
        assert up.status_code == 201, up.text
        made = api.post("/v1/plants", json={"description": small_description(up.json()["sha256"])})
        assert made.status_code == 201, made.text
    plant_id = made.json()["id"]
    local = local_plant(fmu)
    csv_file = tmp_path / "rig-3.csv"
    csv_file.write_bytes(as_csv(synthetic(local, {"damper_friction": 100.0}, seed=11), local))

    with new_page(browser, "report_page_fmu", server) as page:
        page.goto(server.base_url + "/")
        option = page.locator(f'#plant option[value="{plant_id}"]')
        expect(option).to_have_count(1)
        assert "quarter_car_small" in option.inner_text()
        page.select_option("#plant", plant_id)
        page.set_input_files("#record-file", str(csv_file))
        page.fill("#asset", "rig-3")
        page.click("#diagnose-button")
        wait_for_diagnosis(page, None)
        expect(page.locator("#verdict-status")).to_have_text("Explained")
        assert "damper friction" in page.inner_text("#verdict-text")
        candidates = table_rows(page, "#candidates")
        assert candidates[0][1] == "damper friction", candidates
        names = {f["name"] for f in images_loaded(page, "#figures img")}
        assert "overlay_a_body" in names, names
        expect(page.locator("#alert-error")).to_have_count(0)


@pytest.mark.slow  # 33 s
@needs_browser
def test_report_page_shows_errors_and_warnings_at_the_top(
    start_server: ServerFactory, browser: Any, tmp_path: Path
) -> None:
    """Issue 53, item 5: errors and warnings land at the top of the page (in the viewport, above the fold),
    not below the form; each error says what to fix in the page's terms (no HTTP route); a new action clears
    the old ones; no request gets a server error on these paths (a new drive's history included)."""
    server = start_server()  # no pattern set: identification cannot choose one
    expect = playwright().expect
    with server.client() as api:
        record = simulate(api, 0.0055).json()
    # a malformed CSV: the header names a column the record format does not know
    bad_csv = tmp_path / "press-7-bad.csv"
    bad_csv.write_text("time,v2\n0,0.1\n0.0001,0.2\n")
    # 0.1 ms samples declared at 1 ms (issue 50's CSV), as a whole request body: one candidate effect keeps
    # the diagnosis short; its answer says to check the sample interval
    slow = {**record, "sample_interval": 10 * record["sample_interval"]}
    slow_file = tmp_path / "press-7-slow.json"
    slow_file.write_text(json.dumps({"record": slow, "effects": ["motor_coulomb_friction"]}))

    with new_page(browser, "report_page_alerts", server) as page:
        page.goto(server.base_url + "/")
        expect(page.locator("#alerts")).to_be_empty()

        # (a) a failed upload: the server's message at the top, in view
        page.set_input_files("#record-file", str(bad_csv))
        page.fill("#sample-interval", "0.0001")
        page.click("#diagnose-button")
        error = page.locator("#alert-error")
        expect(error).to_contain_text("unknown channel 'time' in the CSV header")
        assert error.get_attribute("role") == "alert"
        in_view_at_the_top(page, "#alert-error")
        expect(page.locator("#message")).to_have_text("")  # not a second copy below the form

        # (b) a diagnosis with warnings, of a drive new to the service: the warnings show at the top, in view;
        # the old error is gone; the drive's history holds the diagnosis, with no trend and no figure yet
        page.set_input_files("#record-file", str(slow_file))
        page.fill("#sample-interval", "")
        page.fill("#asset", "press-9")
        page.click("#diagnose-button")
        expect(error).to_have_count(0)
        wait_for_diagnosis(page, None)
        warnings = page.locator("#alert-warnings")
        expect(warnings).to_contain_text("Check before acting on this diagnosis")
        expect(warnings.locator('li[data-code="sample_interval"]')).to_contain_text("is the sample interval")
        in_view_at_the_top(page, "#alert-warnings")
        expect(page.locator("#message")).to_have_text("Diagnosis done.")
        expect(page.locator("#history tbody tr")).to_have_count(1)
        expect(page.locator("#trend")).to_contain_text("No trend yet")
        expect(page.locator("#trend-figure")).to_be_hidden()
        expect(error).to_have_count(0)

        # the identification needs a pattern set and none is stored: what to do on this page, not in the API
        page.click("#identify-button")
        expect(error).to_contain_text("No pattern set for channel v2")
        text = error.inner_text()
        assert '"Diagnose"' in text and "backlash train --channel v2" in text, text
        assert "/v1/" not in text and "POST" not in text and "any_set" not in text, text
        expect(warnings).to_have_count(0)  # a new action cleared the diagnosis's warnings
        in_view_at_the_top(page, "#alert-error")

        # a drive without history, asked for at the bottom of the page: the page scrolls up to say so
        page.fill("#history-asset", "new-drive")
        page.evaluate("window.scrollTo(0, document.body.scrollHeight)")
        page.click("#asset-button")
        expect(error).to_contain_text("Drive new-drive has no history yet")
        assert "/v1/" not in error.inner_text()
        in_view_at_the_top(page, "#alert-error")

        # the service does not answer (the connection lost): said at the top too
        page.route("**/v1/assets/**", lambda route: route.abort())
        page.click("#asset-button")
        expect(error).to_contain_text("The service did not answer")
        in_view_at_the_top(page, "#alert-error")
        statuses = {status for status, what in page.responses.seen if "/v1/" in what}
        assert {202, 404, 422} <= statuses, page.responses.seen


@needs_browser
def test_report_page_with_an_api_key(start_server: ServerFactory, browser: Any) -> None:
    """With a key, the page and its files load without it; the page asks for the key, keeps it in
    sessionStorage and sends it with every API call and figure."""
    server = start_server(api_key=API_KEY)
    expect = playwright().expect
    with new_page(browser, "report_page_api_key", server) as page:
        response = page.goto(server.base_url + "/")
        assert response is not None and response.status == 200, response and response.text()
        with server.client(headers={"X-API-Key": API_KEY}) as api:  # a drive with one identification
            set_id = train(api, SMALL_TRAINING)["pattern_set_id"]
            identify(api, simulate(api, 0.005).json(), set_id, "2026-10-01T08:00:00Z")
        expect(page.locator("#key-form")).to_be_visible()
        expect(page.locator("#alert-error")).to_contain_text('type it under "API key"')
        in_view_at_the_top(page, "#alert-error")
        page.fill("#api-key", API_KEY)
        page.click("#key-form button")
        expect(page.locator("#pattern-set option")).to_have_count(2)  # the key opened GET /v1/pattern-sets
        expect(page.locator("#alerts")).to_be_empty()  # a new action clears the old error
        assert page.evaluate("sessionStorage.getItem('backlash-api-key')") == API_KEY
        page.fill("#history-asset", ASSET)
        page.click("#asset-button")
        expect(page.locator("#history tbody tr")).to_have_count(1)
        (figure,) = images_loaded(page, "#trend-image")  # fetched with the key
        assert figure["width"] > 100, figure


def test_page_files_are_packaged() -> None:
    """The template, script and style sheet are package data (the container installs the package only)."""
    import tomllib

    from app.web.routes import STATIC_DIR, TEMPLATE_DIR

    pyproject = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text())
    patterns = pyproject["tool"]["setuptools"]["package-data"]["app.web"]
    root = TEMPLATE_DIR.parent
    shipped = {p for pattern in patterns for p in root.glob(pattern)}
    assert {TEMPLATE_DIR / "report.html", STATIC_DIR / "report.js", STATIC_DIR / "report.css"} <= shipped
