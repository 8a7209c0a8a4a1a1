"""The hand-written documentation stays short, undated and whole.

README.md is for a newcomer: at most 150 lines and no dates (a measurement is written once, with its machine and
load, in docs/benchmarks.md, which names no commits). README.md and docs/*.md together stay under 25,000 words,
counted as ``wc -w`` counts them (whitespace-separated tokens). docs/results/ is not counted: evaluate.py generates
its report.md and metrics files. Every section the code, the tests or the docs cite by name (``docs/environment.md,
"Sensing"``) or by number (``docs/model.md §4.3``) exists, as a heading or as a paragraph's bold lead
(``**Start.**``).
"""

import re
from pathlib import Path

import pytest
from conftest import ROOT

README_LINES = 150
WORDS = 25_000
MONTHS = "January|February|March|April|May|June|July|August|September|October|November|December"
DATE = re.compile(rf"\b20\d\d-\d\d-\d\d\b|\b(?:{MONTHS})\s+(?:\d{{1,2}},?\s+)?20\d\d\b|\(this session\)")
CITATION = re.compile(r'docs/([\w/]+)\.md(?:, \\?"([^"\\]+?)\\?"| §(\d+(?:\.\d+)?))')
CITING = ("waterair", "tests", "conf", "hydra_plugins", "scripts", "docs", ".ci")
"""Folders whose files may cite the docs (docs/results/ is generated and skipped)."""


def hand_written_docs(root: Path = ROOT) -> list[Path]:
    """README.md and docs/*.md: what people write (docs/results/ holds what evaluate.py writes)."""
    return [root / "README.md", *sorted((root / "docs").glob("*.md"))]


def words(paths: list[Path]) -> int:
    return sum(len(path.read_text().split()) for path in paths)


def dates(text: str) -> list[str]:
    return [match.group(0) for match in DATE.finditer(text)]


def readme_problems(text: str) -> list[str]:
    problems = []
    if (lines := len(text.splitlines())) > README_LINES:
        problems.append(f"README.md has {lines} lines; at most {README_LINES}")
    if found := dates(text):
        problems.append(f"README.md holds dates {found}: a measurement's date belongs in git, not in the README")
    return problems


def sections(doc: Path) -> list[str]:
    """The headings of ``doc`` and the bold leads of its paragraphs, without their markup."""
    found = []
    for line in doc.read_text().splitlines():
        if line.startswith("#"):
            found.append(line.lstrip("#").strip())
        elif line.startswith("**"):
            found.append(line[2:])
    return found


def citing_files(root: Path = ROOT) -> list[Path]:
    top = [root / name for name in ("README.md", "Makefile", "pyproject.toml", "train.py", "evaluate.py")]
    nested = [
        path
        for folder in CITING
        for path in sorted((root / folder).rglob("*"))
        if path.is_file()
        and path.suffix in {".py", ".md", ".yaml", ".sh", ".toml", ""}
        and "__pycache__" not in path.parts
        and path.relative_to(root).parts[:2] != ("docs", "results")
    ]
    return [path for path in top + nested if path.is_file()]


def dangling_citations(root: Path = ROOT) -> list[str]:
    """``file: citation`` for each cited section no doc has. A citation may run over a line break, also in a
    ``#`` comment."""
    missing = []
    for path in citing_files(root):
        try:
            text = re.sub(r"\n\s*(?:#\s*)?", " ", path.read_text())
        except UnicodeDecodeError:
            continue
        for match in CITATION.finditer(text):
            doc, name, number = match.groups()
            target = root / "docs" / f"{doc}.md"
            heads = sections(target) if target.exists() else []
            if name:
                found = any(head.startswith(name) for head in heads)
            else:
                found = any(re.match(rf"{re.escape(number)}[. ]", head) for head in heads)
            if not found:
                missing.append(f"{path.relative_to(root)}: {match.group(0)}")
    return missing


def test_the_readme_is_short_and_undated():
    assert readme_problems((ROOT / "README.md").read_text()) == []


def test_the_hand_written_docs_stay_under_the_word_budget():
    counts = {str(path.relative_to(ROOT)): words([path]) for path in hand_written_docs()}
    assert sum(counts.values()) <= WORDS, counts


COMMIT = re.compile(r"\b(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b")


def test_the_benchmarks_hold_the_latest_values_not_the_commits_that_measured_them():
    """docs/benchmarks.md is a reference: the history, with its commits, is git's."""
    assert COMMIT.findall((ROOT / "docs" / "benchmarks.md").read_text()) == []
    assert COMMIT.findall("measured at 1d006cd, then c1eafe8") == ["1d006cd", "c1eafe8"]


def test_no_doc_heading_carries_a_date():
    headings = [line for path in hand_written_docs() for line in path.read_text().splitlines() if line.startswith("#")]
    assert [heading for heading in headings if dates(heading)] == []


def test_every_cited_section_exists():
    assert dangling_citations() == []


@pytest.mark.parametrize(
    "text",
    [
        "line\n" * (README_LINES + 1),
        "measured 2026-11-25 on the VM",
        "measured in November 2026",
        "measured on November 25, 2026",
        "faster (this session)",
    ],
)
def test_the_readme_checks_can_fail(text):
    assert readme_problems(text)


def test_the_checks_catch_an_overlong_doc_and_a_missing_section(tmp_path):
    doc = "docs" + "/model.md"  # written apart, so that this file cites nothing itself
    (tmp_path / "docs").mkdir()
    (tmp_path / "README.md").write_text("word " * (WORDS + 1))
    (tmp_path / doc).write_text("## 4. Channel gain\n**Start.** text\n")
    (tmp_path / "waterair").mkdir()
    (tmp_path / "waterair" / "m.py").write_text(
        f'"""{doc} §4, {doc} §5, {doc}, "Start", {doc}, "Gone"\n"""\n# ({doc}, "Split\n# over lines")\n'
    )
    assert words(hand_written_docs(tmp_path)) > WORDS
    assert dangling_citations(tmp_path) == [
        f"waterair/m.py: {doc} §5",
        f'waterair/m.py: {doc}, "Gone"',
        f'waterair/m.py: {doc}, "Split over lines"',
    ]
