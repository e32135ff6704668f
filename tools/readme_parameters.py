"""Write the README's parameter table from the node's parameter table (``ros.parameters.readme_table``).

Usage: .venv/bin/python tools/readme_parameters.py   (``test/test_docs.py`` fails while they differ)
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from linkage_monitor.ros.parameters import readme_table  # noqa: E402 - the repository's package, not an installed one


def with_table(readme: str, table: str) -> str:
    """``readme`` with the markdown table of its ``## Parameters`` section replaced by ``table``."""
    head, section = readme.split("\n## Parameters", 1)
    section, tail = section.split("\n## ", 1)
    lines = section.split("\n")
    rows = [k for k, line in enumerate(lines) if line.startswith("|")]
    lines[rows[0]:rows[-1] + 1] = table.split("\n")
    return head + "\n## Parameters" + "\n".join(lines) + "\n## " + tail


def main() -> None:
    path = ROOT / "README.md"
    text = path.read_text(encoding="utf-8")
    new = with_table(text, readme_table())
    if new != text:
        path.write_text(new, encoding="utf-8")
        print(f"{path.relative_to(ROOT)}: parameter table written")
    else:
        print(f"{path.relative_to(ROOT)}: parameter table already up to date")


if __name__ == "__main__":
    main()
