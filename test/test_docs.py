"""The documentation describes the software as it is.

- every repository path that README.md and docs/*.md name (in backticks, or as a markdown link)
  exists in the working tree;
- README, docs (their prose and their fenced code blocks), the project's Python files and every
  file under test/, bench/ and tools/ (this one too) speak of the software, not of the work that
  made it: no work periods, numbered iterations, tracker numbers, numbered seeds, dates or commit
  hashes (CHANGELOG.md is where history goes, by version);
- package.xml and setup.py carry the version of the newest CHANGELOG.md entry;
- the README's parameter table is the live node's parameter table (ros/parameters.py), row for row.

Plain file checks: no ROS (ros/parameters.py imports no rclpy).
"""

from __future__ import annotations

import fnmatch
import itertools
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

# not part of the repository: virtual environments, build and run outputs, generated code
SKIP_DIRS = {".git", "build", "out", "__pycache__", ".pytest_cache", ".hypothesis", ".mypy_cache", "install",
             "log"}
GENERATED = {Path("linkage_monitor/msg"), Path("can_msgs")}

# extensions of the files a doc names; a bare file name (no folder) is checked for these only,
# since a doc's examples name the user's own files (`my_tractor.yaml`, `lift.mcap`)
PATH_EXTENSIONS = {"py", "md", "yaml", "yml", "png", "json", "sh", "msg", "dbc", "log", "lock", "mcap", "db3",
                   "txt", "xml", "ini", "cfg", "toml", "csv"}
BARE_NAME_EXTENSIONS = {"py", "md", "msg", "sh"}
# a colcon workspace's folders, named where the docs explain a colcon build
WORKSPACE = ("src/", "install/", "build/", "log/", "share/")
OUTSIDE_REPO = ("/work/", "/home/", "/root/", "/tmp/", "/mnt/")

# this file is one of those checked, so the list must not match itself: each word begins with \b,
# which in the text here is the letter b glued to the word (no word boundary there)
HISTORY = re.compile(r"\bsessions?\b|\bround[ -]\d|\bissue \d|\bissues? #\d|`[0-9a-f]{7,40}`"
                     r"|\bmeasured on \d|\b20\d\d-[01]\d-[0-3]\d\b|\bseed 0\d\d\b", re.IGNORECASE)
# a bare commit hash in prose ("on 27a08e0"): 7-12 lowercase hex characters, digits and letters mixed
BARE_HASH = re.compile(r"(?<![\w.#/-])(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,12}(?![\w-])")


def _repo_paths() -> tuple[set[str], set[str]]:
    """Every file and folder of the working tree (relative, posix), and every file's name."""
    paths: set[str] = set()
    names: set[str] = set()
    for dirpath, dirnames, filenames in os.walk(ROOT):
        rel = Path(dirpath).relative_to(ROOT)
        dirnames[:] = [d for d in dirnames if d not in SKIP_DIRS and not d.startswith(".venv")
                       and not d.endswith(".egg-info") and rel / d not in GENERATED]
        for name in [*dirnames, *filenames]:
            paths.add((rel / name).as_posix())
        names.update(filenames)
    return paths, names


PATHS, NAMES = _repo_paths()
TOP_LEVEL = {p for p in PATHS if "/" not in p}


def _expand_braces(word: str) -> list[str]:
    m = re.search(r"\{([^{}]*)\}", word)
    if not m:
        return [word]
    return list(itertools.chain.from_iterable(
        _expand_braces(word[:m.start()] + alt + word[m.end():]) for alt in m.group(1).split(",")))


def _exists(path: str, *, suffix: bool) -> bool:
    """``path`` (maybe a glob) is a file or folder of the repository; with ``suffix``, the end of one."""
    path = path.rstrip("/")
    if any(c in path for c in "*?["):
        pattern = path if not suffix else "*" + path
        return any(fnmatch.fnmatchcase(p, pattern) or (suffix and fnmatch.fnmatchcase(p, path)) for p in PATHS)
    return path in PATHS or (suffix and any(p.endswith("/" + path) for p in PATHS))


def _strip_fences(text: str) -> str:
    """The text without its fenced code blocks (commands and listings, not references)."""
    return re.sub(r"^```.*?^```", "", text, flags=re.MULTILINE | re.DOTALL)


def _word_problem(word: str) -> str | None:
    """Why ``word`` (one whitespace-separated word of a code span) names no repository path, or
    None when it is not meant as one or exists."""
    word = word.strip("'\",;:()[]")
    if word.endswith(".") and not word.endswith("/."):
        word = word[:-1]
    if not word or word.startswith(("-", "~", "$", ".venv", "out/", *WORKSPACE)) or any(
            c in word for c in "<>=$@:|") or "://" in word:
        return None
    if word.startswith("/"):
        return f"{word}: outside the repository" if word.startswith(OUTSIDE_REPO) else None
    ext = word.rsplit(".", 1)[-1] if "." in word.rsplit("/", 1)[-1] else ""
    if "/" not in word:
        if ext in BARE_NAME_EXTENSIONS and not word.startswith(("linkage_monitor.", ".")):
            return None if any(_exists(w, suffix=True) or w in NAMES for w in _expand_braces(word)) \
                else f"{word}: no such file in the repository"
        return None
    first = word.split("/", 1)[0]
    parts = [p for p in word.split("/") if p]
    if any(p.isupper() for p in parts):   # a placeholder: DIR/bags.parquet
        return None
    if not ext and not word.endswith("/") and parts[-1][:1].isupper():   # a message type: pkg/Type
        return None
    if first in TOP_LEVEL:
        ok = all(_exists(w, suffix=False) for w in _expand_braces(word))
        return None if ok else f"{word}: no such path in the repository"
    if ext in PATH_EXTENSIONS or (word.endswith("/") and re.fullmatch(r"[a-z_0-9/]+", word)):
        ok = all(_exists(w, suffix=True) for w in _expand_braces(word))
        return None if ok else f"{word}: no such path in the repository"
    return None


def _problems(doc: Path, text: str | None = None) -> list[str]:
    """What is wrong with the paths ``doc`` (its ``text``, read from it if not given) names."""
    text = _strip_fences(doc.read_text(encoding="utf-8") if text is None else text)
    problems = []
    for lineno, line in enumerate(text.splitlines(), 1):
        for span in re.findall(r"`([^`]+)`", line):
            for word in span.split():
                if (why := _word_problem(word)) is not None:
                    problems.append(f"{doc.relative_to(ROOT)}:{lineno}: {why}")
        for target in re.findall(r"\]\(([^)\s]+)\)", line):
            target = target.split("#", 1)[0]
            if not target or "://" in target or target.startswith("mailto:"):
                continue
            if not (doc.parent / target).resolve().exists():
                problems.append(f"{doc.relative_to(ROOT)}:{lineno}: link ({target}): no such path")
    return problems


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_path_a_doc_names_exists(doc: Path) -> None:
    problems = _problems(doc)
    assert problems == [], "\n".join(problems)


def test_the_path_check_sees_a_missing_path() -> None:
    doc = ROOT / "docs" / "a_page.md"
    text = ("See `linkage_monitor/no_such_module.py`, `no_such_helper.py`, `/work/elsewhere/a.txt`,\n"
            "[the page](no_such_page.md), but not `my_tractor.yaml`, `out/demo/live.rrd`, `/diagnostics`,\n"
            "`sensor_msgs/JointState`, `linkage_monitor/HitchState`, `linkage_monitor.msg`, `install/setup.sh`, `DIR/bags.parquet`, `.msg`, [a site](https://ros.org).\n"
            "Real: `linkage_monitor/mechanics/presets/`, `.venv/bin/python bench/bench_step.py`,\n"
            "`mechanics/kernels/live.py`, `linkage_monitor/offline/{fleet,history,spectra}.py`, `bench/bench_*.py`,\n"
            "[the schema](mechanism-schema.md).\n"
            "```\nlinkage_monitor/fenced_is_not_a_reference.py\n```\n")
    assert _problems(doc, text) == [
        "docs/a_page.md:1: linkage_monitor/no_such_module.py: no such path in the repository",
        "docs/a_page.md:1: no_such_helper.py: no such file in the repository",
        "docs/a_page.md:1: /work/elsewhere/a.txt: outside the repository",
        "docs/a_page.md:2: link (no_such_page.md): no such path"]


def _is_text(path: Path) -> bool:
    """A file to read as text: no NUL byte (a recording such as test/fixtures/rerun/*.rrd has them)."""
    return b"\0" not in path.read_bytes()


def _history_files() -> list[Path]:
    """The docs, every text file under test/, bench/ and tools/, the package's and the launch files'
    code, the configs and the build files."""
    files = [*DOCS]
    for folder in ("test", "bench", "tools", "linkage_monitor", "launch"):
        for path in sorted((ROOT / folder).rglob("*")):
            rel = path.relative_to(ROOT)
            if (path.is_file() and not SKIP_DIRS.intersection(rel.parts)
                    and not any(rel.is_relative_to(g) for g in GENERATED)
                    and (path.suffix in {".py", ".sh"} or folder in {"test", "bench", "tools"} and _is_text(path))):
                files.append(path)
    files += [ROOT / "config" / p for p in sorted(os.listdir(ROOT / "config")) if p.endswith(".yaml")]
    files += [ROOT / "Makefile", ROOT / "setup.py", ROOT / "CMakeLists.txt", ROOT / "package.xml"]
    return files


def _history_hits(path: Path, text: str | None = None) -> list[str]:
    """The history in the file ``path`` (its ``text``, read from it if not given), line by line; a
    markdown file is checked whole, its fenced code blocks too, and for bare commit hashes besides."""
    hits = []
    prose = path.suffix == ".md"
    text = path.read_text(encoding="utf-8") if text is None else text
    for lineno, line in enumerate(text.splitlines(), 1):
        found = [m.group(0) for m in HISTORY.finditer(line)]
        if prose:
            found += [m.group(0) for m in BARE_HASH.finditer(line)]
        if found:
            hits.append(f"{path.relative_to(ROOT)}:{lineno}: {', '.join(found)}")
    return hits


def test_no_history_in_docs_and_code() -> None:
    """History (what was done when, by which commit) belongs in CHANGELOG.md and version control."""
    hits = [hit for path in _history_files() for hit in _history_hits(path)]
    assert hits == [], "\n".join(hits)


def test_the_history_check_sees_history() -> None:
    # the examples are put together here, so that this file itself (one of the files checked) holds none
    commit = "27a08" + "e0"
    lines = ["Measured in the ninth Ses" + "sion.", "As in rou" + "nd 2.", "The rou" + "nd-1/2 solver.",
             "See iss" + "ue 11.", f"On `{commit}`.", f"On {commit} too.", "meas" + "ured on 20" + "26-11-24.",
             "As in se" + "ed 003.",
             "Clean: 0.5 M poses/s, 1e-9, 0x1cfe0b1, 101325 Pa, the issues a user meets, round-trip, seed 0, "
             "2026-01-01T00:00:00Z."]
    assert [bool(HISTORY.search(line) or BARE_HASH.search(line)) for line in lines] == [True] * 8 + [False]


def test_the_history_check_reads_fenced_code_blocks() -> None:
    doc = ROOT / "docs" / "a_page.md"
    text = "Prose.\n```sh\ngit checkout 27a08" + "e0   # as of rou" + "nd 3\n```\n"
    assert _history_hits(doc, text) == ["docs/a_page.md:3: rou" + "nd 3, 27a08" + "e0"]


def _newest_changelog_version() -> str:
    for line in (ROOT / "CHANGELOG.md").read_text(encoding="utf-8").splitlines():
        if line.startswith("## ["):
            m = re.search(r"\[(\d+\.\d+\.\d+[^\]]*)\]", line) or re.search(r"\((\d+\.\d+\.\d+[^)]*)\)", line)
            assert m, f"CHANGELOG.md: the newest entry names no version: {line}"
            return m.group(1)
    raise AssertionError("CHANGELOG.md has no '## [...]' entry")


def test_versions_agree_with_the_changelog() -> None:
    newest = _newest_changelog_version()
    package_xml = re.search(r"<version>([^<]+)</version>", (ROOT / "package.xml").read_text(encoding="utf-8"))
    setup_py = re.search(r"\bversion\s*=\s*[\"']([^\"']+)[\"']", (ROOT / "setup.py").read_text(encoding="utf-8"))
    assert package_xml and setup_py
    assert (package_xml.group(1), setup_py.group(1)) == (newest, newest)


def test_the_readme_parameter_table_is_the_node_parameter_table() -> None:
    """The README's table, row for row, is ``ros.parameters.readme_table`` (the table the node declares
    its parameters from); tools/readme_parameters.py writes it."""
    from linkage_monitor.ros.parameters import readme_table

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("\n## Parameters", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("|")]
    assert rows == readme_table().splitlines(), "README.md's parameter table differs: run tools/readme_parameters.py"
