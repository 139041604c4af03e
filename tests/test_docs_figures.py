"""Figures that cannot go stale: every generated table of README.md and docs/ says what its committed report says.

``docs/gen.py`` writes each measurement table between ``<!-- gen:NAME -->`` and ``<!-- /gen:NAME -->``
from the report its renderer reads (docs/development.md, "The documentation site"). These tests
run its check on the repository, and show on a scratch page that a changed figure is caught and
rewritten.
"""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]
GEN = ROOT / "docs" / "gen.py"


def load_gen() -> ModuleType:
    """``docs/gen.py`` as a module (docs/ is not a package)."""
    spec = importlib.util.spec_from_file_location("docs_gen", GEN)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["docs_gen"] = module  # dataclasses resolve the module's annotations through sys.modules
    spec.loader.exec_module(module)
    return module


def test_every_generated_figure_matches_its_committed_report() -> None:
    done = subprocess.run([sys.executable, str(GEN), "--check"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"{done.stderr}{done.stdout}"
    assert "every generated region up to date" in done.stdout


def test_every_renderer_is_used_and_every_region_has_a_renderer() -> None:
    gen = load_gen()
    used = gen.used_regions(gen.default_files())
    assert used == set(gen.RENDERERS), (
        f"unused renderers: {set(gen.RENDERERS) - used}; unknown: {used - set(gen.RENDERERS)}"
    )


def test_the_readme_has_the_validation_table_and_it_links_only_to_committed_reports() -> None:
    gen = load_gen()
    text = (ROOT / "README.md").read_text()
    region = next(m for m in gen.REGION.finditer(text) if m.group("name") == "validation-summary")
    links = re.findall(r"\]\(([^)#]+)\)", region.group("body"))
    assert links, "the validation table links to no report"
    for link in links:
        assert (ROOT / link).is_file(), f"README's validation table links to {link}, which is not a committed file"
        assert link.startswith("docs/validation/"), link


def scratch_page(tmp_path: Path, name: str) -> Path:
    """A page holding one empty region of renderer ``name``."""
    page = tmp_path / "page.md"
    page.write_text(f"# scratch\n\n<!-- gen:{name} -->\n<!-- /gen:{name} -->\n\nafter\n")
    return page


def test_a_changed_figure_is_named_stale_and_rewritten(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gen = load_gen()
    page = scratch_page(tmp_path, "width-coverage")
    assert gen.main([str(page)]) == 0  # rendered from docs/validation/width/*.json
    rendered = page.read_text()
    assert (
        "282/291 = 96.9 % [94.2, 98.4]" in rendered
    )  # seed 229, every verdict, docs/validation/width/held-out-seed229.json
    assert gen.main([str(page), "--check"]) == 0

    page.write_text(rendered.replace("282/291 = 96.9 %", "282/291 = 97.9 %"))  # a figure typed by hand
    capsys.readouterr()
    assert gen.main([str(page), "--check"]) == 1
    err = capsys.readouterr().err
    assert "page.md:3: gen:width-coverage" in err
    assert "97.9 %" in page.read_text()  # --check changes nothing

    assert gen.main([str(page)]) == 0
    assert page.read_text() == rendered
    assert page.read_text().endswith("after\n")  # text outside the region is kept


def test_an_unknown_renderer_or_an_unpaired_marker_is_an_error(tmp_path: Path) -> None:
    gen = load_gen()
    assert gen.main([str(scratch_page(tmp_path, "no-such-table")), "--check"]) == 2
    page = tmp_path / "open.md"
    page.write_text("<!-- gen:width-coverage -->\nno end\n")
    assert gen.main([str(page), "--check"]) == 2


def test_a_marker_quoted_in_text_is_not_a_region(tmp_path: Path) -> None:
    gen = load_gen()
    page = tmp_path / "quoted.md"
    page.write_text("Tables sit between `<!-- gen:NAME -->` and `<!-- /gen:NAME -->`.\n")
    assert gen.render_file(page) == (page.read_text(), [])


def test_a_region_showing_an_unformatted_placeholder_is_an_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A renderer whose f-string lost its prefix would show ``{pooled_rate('...')}`` instead of the figure (as
    the README's FMU line once did): the page is refused, not written."""
    gen = load_gen()
    monkeypatch.setitem(gen.RENDERERS, "fmu-summary", lambda page: "named first in {pooled_rate('strong_top1')}")
    page = tmp_path / "placeholder.md"
    page.write_text("<!-- gen:fmu-summary -->\nold\n\n<!-- /gen:fmu-summary -->\n")
    with pytest.raises(gen.RegionError, match="unformatted placeholder"):
        gen.render_file(page)
    monkeypatch.setitem(gen.RENDERERS, "fmu-summary", lambda page: "routes such as GET /v1/assets/{a}/history")
    assert "{a}" in gen.render_file(page)[0]
