"""The generated blocks of README.md and docs/ are what their results files give (bench/doc_blocks.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench import doc_blocks
from bench.doc_tables import BLOCKS, PAGES

ROOT = Path(__file__).resolve().parent.parent
needs_docs = pytest.mark.skipif(not (ROOT / "docs").is_dir(), reason="docs/ is not in this checkout")


@needs_docs
def test_every_generated_block_is_current() -> None:
    stale = doc_blocks.stale()
    assert not stale, "stale generated docs (regenerate with `python -m bench.doc_blocks`): " + "; ".join(stale)


@needs_docs
def test_every_block_is_on_a_page_and_every_page_block_is_known() -> None:
    used = {n for p in doc_blocks.pages() for n in doc_blocks.names_in(p.read_text(encoding="utf-8"))}
    assert used == set(BLOCKS), f"unused: {sorted(set(BLOCKS) - used)}; unknown: {sorted(used - set(BLOCKS))}"
    assert all((ROOT / p).is_file() for p in PAGES)


def _page(tmp_path: Path, body: str) -> Path:
    (tmp_path / "docs").mkdir()
    (tmp_path / "README.md").write_text("# r\n", encoding="utf-8")
    page = tmp_path / "docs" / "a.md"
    page.write_text(f"intro\n\n{doc_blocks.start('x')}\n{body}\n{doc_blocks.END}\n\noutro\n", encoding="utf-8")
    return page


def test_a_hand_edited_block_is_stale_and_render_restores_it(tmp_path: Path) -> None:
    page = _page(tmp_path, "| a | 1.5 |")
    blocks = {"x": lambda: "| a | 1.4 |"}
    assert doc_blocks.stale(tmp_path, blocks, whole={}) == ["docs/a.md: x"]
    fresh = doc_blocks.render(page.read_text(encoding="utf-8"), blocks)
    assert "| a | 1.4 |" in fresh and "1.5" not in fresh and fresh.startswith("intro\n") and fresh.endswith("outro\n")
    page.write_text(fresh, encoding="utf-8")
    assert doc_blocks.stale(tmp_path, blocks, whole={}) == []


def test_a_stale_whole_page_is_named(tmp_path: Path) -> None:
    _page(tmp_path, "y")
    (tmp_path / "docs" / "b.md").write_text("old\n", encoding="utf-8")
    assert doc_blocks.stale(tmp_path, {"x": lambda: "y"}, whole={"docs/b.md": lambda: "new\n"}) == ["docs/b.md"]


def test_an_unknown_block_name_is_an_error(tmp_path: Path) -> None:
    page = _page(tmp_path, "y")
    with pytest.raises(ValueError, match=r"docs/a\.md: unknown generated block 'x'"):
        doc_blocks.render(page.read_text(encoding="utf-8"), {}, where="docs/a.md")


def test_only_the_named_blocks_are_rewritten() -> None:
    text = f"{doc_blocks.start('x')}\nold x\n{doc_blocks.END}\n{doc_blocks.start('y')}\nold y\n{doc_blocks.END}\n"
    fresh = doc_blocks.render(text, {"x": lambda: "new x", "y": lambda: "new y"}, only=["y"])
    assert "old x" in fresh and "new y" in fresh and "old y" not in fresh
