"""The test folder's layout: code the tests share lives in test/support (harnesses, fixtures, helpers)
and test/oracles (independent references); a test module imports neither another test module nor
anything from one, so each one runs alone and moving a test never breaks another.

Plain file checks: the modules are parsed, not imported.
"""

from __future__ import annotations

import ast
from pathlib import Path

TEST_DIR = Path(__file__).resolve().parent


def _imported_test_modules(source: str) -> list[str]:
    """The test modules (``test_*``, also as ``test.test_*`` or ``.test_*``) that ``source`` imports,
    at any depth (a function's own imports too)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            modules = [node.module or ""]
            if not node.module:   # from . import test_x
                modules = [alias.name for alias in node.names]
        else:
            continue
        for module in modules:
            parts = module.split(".")
            if parts[0] == "test":
                parts = parts[1:]
            if parts and parts[0].startswith("test_"):
                found.append(module)
    return found


def test_no_test_module_imports_another() -> None:
    hits = [f"{path.relative_to(TEST_DIR.parent)}: imports {module}"
            for path in sorted(TEST_DIR.rglob("*.py")) if "__pycache__" not in path.parts
            for module in _imported_test_modules(path.read_text(encoding="utf-8"))]
    assert hits == [], "shared code belongs in test/support or test/oracles:\n" + "\n".join(hits)


def test_the_layout_check_sees_a_test_module_import() -> None:
    source = ("import test_wire\nfrom test_wire import assert_bytes\nfrom test.test_node import T0\n"
              "from . import test_chain\nfrom .test_spin import spin\n"
              "def f():\n    from test_node_recording import pose\n"
              "import testing\nfrom support.fixtures import FIXTURES\nfrom oracles import markers\n")
    assert _imported_test_modules(source) == ["test_wire", "test_wire", "test.test_node", "test_chain", "test_spin",
                                              "test_node_recording"]
