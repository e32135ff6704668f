"""Where the test mechanisms and recordings are: test/fixtures (YAML mechanisms, a Rerun recording)."""

from __future__ import annotations

from pathlib import Path

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
