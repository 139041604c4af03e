"""Settings (app/core/config.py): BACKLASH_* environment variables, validated."""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs
import pytest
from pydantic import ValidationError

from app.core.config import Settings


@pytest.fixture(autouse=True)
def no_backlash_env(monkeypatch: pytest.MonkeyPatch) -> None:
    for k in list(os.environ):
        if k.startswith("BACKLASH_"):
            monkeypatch.delenv(k)


def test_defaults() -> None:
    s = Settings()
    assert s.db_path == platformdirs.user_data_path("backlash") / "patterns.sqlite3"  # wherever the CLI runs
    assert s.api_key is None
    assert (s.max_body_bytes, s.max_batch_cases, s.workers, s.log_level) == (32 << 20, 64, 1, "INFO")


def test_environment_variables_are_read(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("BACKLASH_DB_PATH", str(tmp_path / "x.sqlite3"))
    monkeypatch.setenv("BACKLASH_API_KEY", "a-long-enough-key")
    monkeypatch.setenv("BACKLASH_MAX_BODY_BYTES", "2048")
    monkeypatch.setenv("BACKLASH_MAX_BATCH_CASES", "3")
    monkeypatch.setenv("BACKLASH_WORKERS", "2")
    monkeypatch.setenv("BACKLASH_LOG_LEVEL", "debug")
    s = Settings()
    assert s.db_path == tmp_path / "x.sqlite3"
    assert s.api_key is not None and s.api_key.get_secret_value() == "a-long-enough-key"
    assert "a-long-enough-key" not in repr(s)  # the key is never printed
    assert (s.max_body_bytes, s.max_batch_cases, s.workers, s.log_level) == (2048, 3, 2, "DEBUG")


def test_empty_variables_mean_the_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BACKLASH_API_KEY", "")
    assert Settings().api_key is None


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("BACKLASH_WORKERS", "0", "greater than or equal to 1"),
        ("BACKLASH_WORKERS", "many", "valid integer"),
        ("BACKLASH_MAX_BODY_BYTES", "10", "greater than or equal to 1024"),
        ("BACKLASH_MAX_BATCH_CASES", "-1", "greater than or equal to 1"),
        ("BACKLASH_LOG_LEVEL", "loud", "'DEBUG', 'INFO'"),
        ("BACKLASH_API_KEY", "short", "at least 8 characters"),
        ("BACKLASH_DB_PATH", ":memory:", "database file path"),
    ],
)
def test_invalid_values_are_refused(monkeypatch: pytest.MonkeyPatch, name: str, value: str, message: str) -> None:
    monkeypatch.setenv(name, value)
    with pytest.raises(ValidationError, match=message):
        Settings()
