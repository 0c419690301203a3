"""wsnlib.book: the static site from executed notebooks (no kernel needed: copies are faked)."""

import base64
import re
from html.parser import HTMLParser

import nbformat
import pytest

from wsnlib import book, paths

PNG_1PX = base64.b64encode(bytes.fromhex(
    "89504e470d0a1a0a0000000d49484452000000010000000108060000001f15c489"
    "0000000d49444154789c6360f8cfc0f01f0005ff02fea7a8f1b70000000049454e44ae426082")).decode()


def _notebook(title, first_paragraph, executed):
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": paths.KERNEL_NAME, "language": "python", "display_name": "x"}
    params = nbformat.v4.new_code_cell("quick = False\nseed = 0")
    params.metadata["tags"] = ["parameters"]
    code = nbformat.v4.new_code_cell("plot()")
    nb.cells = [
        nbformat.v4.new_markdown_cell(f"# {title}\n\n{first_paragraph}\n\nMore text."),
        params,
        nbformat.v4.new_markdown_cell("Eq. $$\\mu = \\frac{\\rho}{\\lambda + \\rho}$$ and $x_1$; see "
                                      "[notebook 02](02_second.ipynb#Top) and [DOI](https://doi.org/10.1/x)."),
        code,
    ]
    if executed:
        nb.metadata["papermill"] = {"parameters": {"quick": True}}
        for count, cell in enumerate([params, code], start=1):
            cell.execution_count = count
        progress_bar = {"application/vnd.jupyter.widget-view+json": {"model_id": "abc", "version_major": 2,
                                                                     "version_minor": 0},
                        "text/plain": "  0%|          | 0/4"}
        code.outputs = [nbformat.v4.new_output("display_data", data={"image/png": PNG_1PX}),
                        nbformat.v4.new_output("display_data", data=progress_bar)]
        nb.metadata["widgets"] = {"application/vnd.jupyter.widget-state+json": {"state": {}}}
    return nb


@pytest.fixture
def project(output_dir, tmp_path, monkeypatch):
    """Two notebooks and one solutions notebook, executed copies in build/executed/."""
    sources = tmp_path / "nbs"
    executed = output_dir / "build" / "executed"
    specs = {"01_first.ipynb": ("01 — First", "**Paper 001, Section II.** Figs. 1–3."),
             "02_second.ipynb": ("02 — Second", "**Paper 002, Table 1.** Fingerprints; uses BROAD."),
             "solutions/01_first_solutions.ipynb": ("01 — First: solutions", "Answers to the exercises.")}
    for name, (title, paragraph) in specs.items():
        for folder, is_executed in ((sources, False), (executed, True)):
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            nbformat.write(_notebook(title, paragraph, is_executed), folder / name)
    monkeypatch.setattr(paths, "NOTEBOOKS", sources)
    return output_dir


class _Resources(HTMLParser):
    """Every URL a page would load (src of any tag, href of <link>) and every <a href>."""

    def __init__(self):
        super().__init__()
        self.loads, self.anchors = [], []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if attrs.get("src"):
            self.loads.append(attrs["src"])
        if tag == "link" and attrs.get("href"):
            self.loads.append(attrs["href"])
        if tag == "a" and attrs.get("href"):
            self.anchors.append(attrs["href"])


def _parse(path):
    parser = _Resources()
    parser.feed(path.read_text(encoding="utf-8"))
    return parser


def test_missing_executed_folder_is_an_error_that_says_what_to_run(output_dir, capsys):
    with pytest.raises(book.BookError, match="make figures"):
        book.build()
    assert book.main([]) == 2
    assert "make figures" in capsys.readouterr().err
    assert not (output_dir / "build" / "executed").exists()


def test_a_missing_or_failed_executed_copy_is_an_error(project):
    executed = project / "build" / "executed"
    (executed / "02_second.ipynb").unlink()
    failed = nbformat.read(executed / "01_first.ipynb", as_version=4)
    failed.cells[-1].outputs = [nbformat.v4.new_output("error", ename="E", evalue="x", traceback=[])]
    nbformat.write(failed, executed / "01_first.ipynb")
    with pytest.raises(book.BookError) as info:
        book.build()
    message = str(info.value)
    assert "02_second.ipynb: no executed copy" in message
    assert "01_first.ipynb: cell 3 failed" in message
    assert "make figures" in message


def test_a_cell_tagged_raises_exception_may_fail(project):
    executed = project / "build" / "executed" / "02_second.ipynb"
    nb = nbformat.read(executed, as_version=4)
    nb.cells[-1].metadata["tags"] = ["raises-exception"]
    nb.cells[-1].outputs = [nbformat.v4.new_output("error", ename="E", evalue="on purpose",
                                                     traceback=["E: on purpose"])]
    nbformat.write(nb, executed)
    book.build()
    assert "on purpose" in (project / "build" / "book" / "02_second.html").read_text(encoding="utf-8")


def test_an_interrupted_executed_copy_is_an_error(project):
    executed = project / "build" / "executed" / "solutions" / "01_first_solutions.ipynb"
    nb = nbformat.read(executed, as_version=4)
    nb.cells[-1].execution_count = None
    nbformat.write(nb, executed)
    with pytest.raises(book.BookError, match="01_first_solutions.ipynb: cell 3 was not executed"):
        book.build()


def test_index_lists_every_notebook_and_its_solutions(project):
    written = book.build()
    site = project / "build" / "book"
    assert [p.relative_to(site).as_posix() for p in written] == [
        "01_first.html", "02_second.html", "credits.html", "index.html", "references.html",
        "solutions/01_first_solutions.html"]
    index = (site / "index.html").read_text(encoding="utf-8")
    anchors = _parse(site / "index.html").anchors
    for href in ("01_first.html", "02_second.html", "solutions/01_first_solutions.html",
                 "references.html", "credits.html"):
        assert href in anchors
    assert "01 — First" in index and "Paper 001, Section II." in index
    assert "De Vito" in index and "Giuberti" in index
    assert "quick" in index
    # Every page has the navigation header, with links that work from its folder.
    assert '<a href="../index.html">Index</a>' in (site / "solutions" / "01_first_solutions.html").read_text()
    for page in written:
        assert 'class="book-nav"' in page.read_text(encoding="utf-8"), page
    credits = (site / "credits.html").read_text(encoding="utf-8")
    assert "CC BY 4.0" in credits and "CC0" in credits and 'href="02_second.html"' in credits


def test_pages_load_nothing_from_the_network(project):
    for page in book.build():
        parsed = _parse(page)
        text = page.read_text(encoding="utf-8")
        assert not [u for u in parsed.loads if re.match(r"\s*(https?:)?//", u)], page
        assert not re.search(r"url\(\s*['\"]?(https?:)?//", text), page
        assert not re.search(r"import\(\s*['\"](https?:)?//", text), page
        assert "mathjax" not in text.lower(), page
        assert "require.min.js" not in text, page
        assert "widget-view" not in text and "widget-state" not in text, page


def test_notebook_pages_embed_figures_formulas_and_link_pages(project):
    book.build()
    page = project / "build" / "book" / "01_first.html"
    loads = _parse(page).loads
    assert any(u.startswith("data:image/png;base64,") for u in loads)
    assert sum(u.startswith("data:image/svg+xml;base64,") for u in loads) == 2  # $$…$$ and $x_1$
    anchors = _parse(page).anchors
    assert "02_second.html#Top" in anchors and "https://doi.org/10.1/x" in anchors
    assert "solutions/01_first_solutions.html" in anchors


def test_the_book_is_deterministic(project):
    first = {p: p.read_bytes() for p in book.build()}
    second = {p: p.read_bytes() for p in book.build()}
    assert first == second


def test_math_outside_code_only():
    text = book.render_math("costs $5 and $6, `$x$` and $y$")
    assert text.startswith("costs $5 and $6, `$x$` and <img")
    assert book.render_math(r"$\notacommand{$") == r'<code class="tex">\notacommand{</code>'
