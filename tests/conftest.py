"""Shared fixtures: tiny sessions written through the project's own writer."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from sessionfactory import make_tiny_session  # noqa: E402


@pytest.fixture
def tiny_session(tmp_path: Path) -> Path:
    return make_tiny_session(tmp_path / "session")
