"""The book: a static HTML site built from the executed notebooks.

Usage::

    python -m wsnlib.book          # or: make book (after make figures)

Reads the executed copies in ``build/executed/`` (and ``build/executed/solutions/``) that
:mod:`wsnlib.reproduce` wrote, and writes ``build/book/``: ``index.html`` (the papers'
questions and a map of which notebook answers which section, figure or table), one page per
notebook (``NN_name.html``, ``solutions/NN_name_solutions.html``), ``references.html`` and
``credits.html``.  Nothing is executed again; a notebook whose executed copy is missing,
failed or was interrupted is an error (exit status 2) that says to run ``make figures``.

Pages are rendered with nbconvert's ``HTMLExporter`` (template ``lab``), already in the
environment.  Jupyter Book is not used: jupyter-book 2 (MyST) needs Node.js, a toolchain this
project does not otherwise have.

The pages load nothing from the network, so they read offline: figures are embedded as data
URIs, and the template's script tags that would fetch require.js, MathJax, mermaid and the
widget manager from a CDN are left out, as are widget outputs (the batch's progress bars:
they need a kernel).  LaTeX in markdown cells (``$...$``, ``$$...$$``) is
drawn instead by matplotlib's mathtext as inline SVG images (the TeX source is their alt
text; what mathtext cannot parse is shown as TeX in ``<code>``).  The output is
deterministic: the same executed notebooks give the same bytes (sorted, no timestamps).
"""

from __future__ import annotations

import argparse
import base64
import html
import io
import re
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import nbformat

from wsnlib import batch_selection, paths

#: The two papers, in our words, and how to cite them.
PAPERS = (
    ("Paper 001",
     'L. De Vito, G. Mazzilli, M. Riccio, C. Sementa, "Improving the Orientation Estimation in a Packet '
     'Loss-affected Wireless Sensor Network for Tracking Human Motion".',
     "A body-worn node streams its inertial and magnetic samples over a low-power radio, and packets get "
     "lost. How much does a lost packet hurt the orientation of the body segment, and how can the harm be "
     "limited? A data-fusion filter (Madgwick's) stays smooth but falls behind during a gap and catches up "
     "slowly; a single-frame estimate (TRIAD) is back at once but jittery. The paper blends the two by "
     "spherical linear interpolation, leaning on the single-frame estimate right after a loss and handing "
     "back to the filter as samples keep arriving."),
    ("Paper 002",
     'M. Giuberti, M. Martalò, G. Ferrari, "A hybrid radio/accelerometric approach to arm posture '
     'recognition".',
     "Can the posture of an arm be recognised from the strength of the radio signals exchanged between "
     "a few nodes on the body and in the room? The paper matches received-signal-strength vectors "
     "against a radio map of trained postures (kNN with Shepard weights, and a probabilistic kNN on "
     "histograms), then keeps only the heading of the radio estimate and takes each segment's pitch "
     "from an accelerometer, placing elbow and wrist one after the other along the arm. Its parameters "
     "are chosen by exhaustive search, and its accuracy and precision are set against a Kinect."),
)

#: (citation HTML, a word that marks a notebook as citing it) for references.html.
REFERENCES = (
    ('S. O. H. Madgwick, "An efficient orientation filter for inertial and inertial/magnetic sensor '
     'arrays", technical report, University of Bristol, 2010.', "Madgwick"),
    ('M. D. Shuster, S. D. Oh, "Three-axis attitude determination from vector observations", <i>Journal '
     "of Guidance and Control</i> 4(1):70–77, 1981 (TRIAD).", "Shuster"),
    ('D. Laidig, T. Seel, "VQF: Highly accurate IMU orientation estimation with bias estimation and '
     'magnetic disturbance rejection", <i>Information Fusion</i> 91:187–204, 2023.', "VQF"),
    ("x-io Technologies, Fusion, an AHRS library by S. Madgwick (Python package <code>imufusion</code>), "
     "github.com/xioTechnologies/Fusion.", "imufusion"),
    ('D. Shepard, "A two-dimensional interpolation function for irregularly-spaced data", Proceedings of '
     "the 23rd ACM National Conference, 1968, pp. 517–524.", "Shepard"),
    ('E. N. Gilbert, "Capacity of a burst-noise channel", <i>Bell System Technical Journal</i> '
     "39(5):1253–1265, 1960.", "Gilbert"),
    ('E. O. Elliott, "Estimates of error rates for codes on burst-noise channels", <i>Bell System '
     "Technical Journal</i> 42(5):1977–1997, 1963.", "Elliott"),
    ("B. Efron, R. J. Tibshirani, <i>An Introduction to the Bootstrap</i>, Chapman &amp; Hall, 1993.",
     "Efron"),
    ("E. Reusens, W. Joseph, B. Latré, B. Braem, G. Vermeeren, E. Tanghe, L. Martens, I. Moerman, "
     'C. Blondia, "Characterization of on-body communication channel and energy efficient topology design '
     'for wireless body area networks", <i>IEEE Transactions on Information Technology in Biomedicine</i> '
     "13(6):933–945, 2009 (on-body path loss of the simulated radio channel, <code>wsnlib.sim.radio</code>).",
     "Reusens"),
    ('Š. Obdržálek et al., "Accuracy and robustness of Kinect pose estimation in the context of coaching '
     'of elderly population", IEEE EMBC 2012, pp. 1188–1193 (the Kinect-like baseline, '
     "<code>wsnlib.sim.optical</code>).", "Obdržálek"),
)

#: (dataset, credit HTML, a word that marks a notebook as using it) for credits.html.
DATASETS = (
    ("BROAD",
     'D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD—A Benchmark for Robust Inertial Orientation '
     'Estimation", <i>Data</i> 6(7):72, 2021, doi:10.3390/data6070072; github.com/dlaidig/broad. Every one '
     "of its 39 trials present in the data folder (17 on CI; IMU recordings with optical ground truth). "
     "License: Creative Commons Attribution 4.0 (CC BY 4.0); the recordings and the reference are the "
     "authors' work.", "BROAD"),
    ("PABR",
     "F. S. Daniş, A. T. Naskali, A. T. Cemgil, C. Ersoy, Position Annotated BLE RSSI Dataset for Indoor "
     "Localization, <i>Pervasive and Mobile Computing</i> 81, 2022; "
     "github.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset. A subset of its BLE RSSI fingerprints and "
     "tracks. License: CC0 1.0 (public domain dedication); cited all the same.", "PABR"),
)

CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; line-height: 1.5; }
nav.book-nav { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; font-size: 15px;
  padding: 8px 16px; margin-bottom: 12px; border-bottom: 1px solid #ccc; background: #f6f8fa; }
nav.book-nav a { margin-right: 1.2em; color: #0b5cad; text-decoration: none; }
nav.book-nav a:hover { text-decoration: underline; }
.book-page { max-width: 980px; margin: 0 auto; padding: 0 16px 32px; }
.book-page table { border-collapse: collapse; width: 100%; font-size: 14px; }
.book-page th, .book-page td { border: 1px solid #d0d7de; padding: 6px 8px; vertical-align: top; text-align: left; }
.book-page th { background: #f6f8fa; }
.book-page td p { margin: 0; }
img.math { vertical-align: middle; }
img.math.display { display: block; margin: 0.6em auto; }
"""

_NOTEBOOK_TEMPLATE = """{%- extends 'index.html.j2' -%}
{%- block html_head_js_requirejs -%}{%- endblock html_head_js_requirejs -%}
{%- block jupyter_widgets -%}{%- endblock jupyter_widgets -%}
{%- block html_head_js_mathjax -%}{%- endblock html_head_js_mathjax -%}
{%- block html_head_js_mermaidjs -%}{%- endblock html_head_js_mermaidjs -%}
{%- block extra_css -%}
<link rel="icon" href="data:,">
<style type="text/css">{{ resources.book_css }}</style>
{%- endblock extra_css -%}
{%- block body_header -%}{{ super() }}
{{ resources.book_nav }}
{%- endblock body_header -%}
"""


_WIDGET = "application/vnd.jupyter.widget-view+json"


class BookError(RuntimeError):
    """The executed notebooks are missing or incomplete."""


@dataclass(frozen=True)
class Page:
    """One notebook of the book: its source, its executed copy and the page it becomes."""

    source: Path
    executed: Path
    href: str  # relative to the book's root, e.g. "01_x.html" or "solutions/01_x_solutions.html"

    @property
    def number(self) -> str:
        return self.source.name[:2]

    @property
    def is_solutions(self) -> bool:
        return self.href.startswith(f"{batch_selection.SOLUTIONS}/")


def executed_folder() -> Path:
    """``build/executed/`` below the output root (not created here)."""
    return paths.output_root() / "build" / "executed"


def book_folder() -> Path:
    """``build/book/`` below the output root."""
    return paths.output_root() / "build" / "book"


def collect_pages(executed_dir: Path | None = None) -> list[Page]:
    """Every notebook of the batch with its executed copy; :class:`BookError` if one is missing or incomplete."""
    executed_dir = executed_folder() if executed_dir is None else executed_dir
    hint = "run `make figures` first (or `python -m wsnlib.reproduce [--quick]`)"
    if not executed_dir.is_dir():
        raise BookError(f"{executed_dir} does not exist: {hint}")
    pages, problems = [], []
    for source in batch_selection.list_batch():
        name = batch_selection.notebook_name(source)
        page = Page(source, executed_dir / name, name[: -len(".ipynb")] + ".html")
        problem = _execution_problem(page.executed)
        if problem:
            problems.append(f"  {name}: {problem}")
        pages.append(page)
    if problems:
        raise BookError(f"incomplete executed notebooks in {executed_dir}:\n" + "\n".join(problems) + f"\n{hint}")
    if not pages:
        raise BookError(f"no notebooks found in {paths.NOTEBOOKS}")
    return pages


def _execution_problem(executed: Path) -> str | None:
    if not executed.is_file():
        return "no executed copy"
    try:
        nb = nbformat.read(executed, as_version=4)
    except (OSError, ValueError) as exc:
        return f"unreadable ({exc})"
    for index, cell in enumerate(nb.cells):
        if cell.cell_type != "code":
            continue
        failed = any(output.get("output_type") == "error" for output in cell.outputs)
        if failed and "raises-exception" not in cell.metadata.get("tags", []):  # tagged: fails on purpose
            return f"cell {index} failed"
        if cell.source.strip() and cell.execution_count is None:
            return f"cell {index} was not executed (interrupted run?)"
    return None


def summary(nb) -> tuple[str, str]:
    """Title (the first heading) and first paragraph (markdown) of a notebook's first markdown cell."""
    markdown = next((cell.source for cell in nb.cells if cell.cell_type == "markdown"), "")
    blocks = [block.strip() for block in re.split(r"\n\s*\n", markdown) if block.strip()]
    title, first = "", ""
    for block in blocks:
        if block.startswith("#") and not title:
            title = block.lstrip("#").strip().splitlines()[0]
        elif not block.startswith("#"):
            first = block
            break
    return title, first


# --- LaTeX without MathJax ----------------------------------------------------------------

_CODE = re.compile(r"(```.*?```|~~~.*?~~~|`[^`\n]*`)", re.S)
_DISPLAY_MATH = re.compile(r"\$\$(.+?)\$\$", re.S)
_INLINE_MATH = re.compile(r"(?<![\\$])\$(?![\s$])([^$\n]+?)(?<![\s\\])\$(?![\d$])")


def render_math(markdown: str) -> str:
    """Replace ``$$...$$`` and ``$...$`` outside code by SVG images of the formula (mathtext)."""
    parts = _CODE.split(markdown)
    for i in range(0, len(parts), 2):  # even parts are outside code
        text = _DISPLAY_MATH.sub(lambda m: _math_html(m.group(1), display=True), parts[i])
        parts[i] = _INLINE_MATH.sub(lambda m: _math_html(m.group(1), display=False), text)
    return "".join(parts)


def _math_html(tex: str, display: bool) -> str:
    tex = " ".join(tex.split())
    try:
        svg = _mathtext_svg(tex, fontsize=15 if display else 12)
    except Exception:  # mathtext knows a subset of TeX: show the rest as source
        return f'<code class="tex">{html.escape(tex)}</code>'
    data = base64.b64encode(svg).decode("ascii")
    css = "math display" if display else "math"
    return f'<img class="{css}" alt="{html.escape(tex)}" src="data:image/svg+xml;base64,{data}">'


def _mathtext_svg(tex: str, fontsize: float) -> bytes:
    import matplotlib as mpl
    from matplotlib.figure import Figure

    with mpl.rc_context({"svg.hashsalt": "wsn-motion", "svg.fonttype": "path", "mathtext.fontset": "cm"}):
        fig = Figure(figsize=(0.1, 0.1))
        fig.text(0, 0, f"${tex}$", fontsize=fontsize)
        buffer = io.BytesIO()
        fig.savefig(buffer, format="svg", bbox_inches="tight", pad_inches=0.02, transparent=True,
                    metadata={"Date": None, "Creator": None, "Format": None, "Type": None})
    return buffer.getvalue()


# --- pages ---------------------------------------------------------------------------------

def _nav(depth: int, extra: tuple[tuple[str, str], ...] = ()) -> str:
    up = "../" * depth
    links = [(f"{up}index.html", "Index"), (f"{up}references.html", "References"),
             (f"{up}credits.html", "Credits"), *extra]
    items = "".join(f'<a href="{html.escape(href)}">{html.escape(text)}</a>' for href, text in links)
    return f'<nav class="book-nav">{items}</nav>'


def _page(title: str, body: str) -> str:
    return ('<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            '<meta name="viewport" content="width=device-width, initial-scale=1.0">\n'
            f'<title>{html.escape(title)}</title>\n<link rel="icon" href="data:,">\n'
            f"<style>{CSS}</style>\n</head>\n<body>\n{_nav(0)}\n"
            f'<main class="book-page">\n{body}\n</main>\n</body>\n</html>\n')


def _markdown(text: str) -> str:
    from nbconvert.filters import markdown2html_mistune

    return markdown2html_mistune(render_math(text))


def _exporter():
    import jinja2
    from nbconvert import HTMLExporter

    loader = jinja2.DictLoader({"book.html.j2": _NOTEBOOK_TEMPLATE})
    exporter = HTMLExporter(template_name="lab", extra_loaders=[loader], embed_images=True)
    exporter.template_file = "book.html.j2"
    return exporter


def render_notebook(nb, title: str, nav: str, exporter=None) -> str:
    """HTML of one executed notebook, with the book's navigation and no network resources."""
    nb = nbformat.from_dict(nb)
    nb.metadata.pop("widgets", None)
    for cell in nb.cells:
        if cell.cell_type == "markdown":
            cell.source = render_math(cell.source)
        elif cell.cell_type == "code":  # widgets (progress bars) need a kernel: left out
            cell.outputs = [output for output in cell.outputs if _WIDGET not in output.get("data", {})]
    exporter = exporter or _exporter()
    resources = {"metadata": {"name": title}, "book_css": CSS, "book_nav": nav}
    body, _ = exporter.from_notebook_node(nb, resources=resources)
    # Links between notebooks point at their pages.
    return re.sub(r'href="(?![a-z]+:)([^"#]*?)\.ipynb(#[^"]*)?"', r'href="\1.html\2"', body)


def _citing(texts: dict[Page, str], word: str) -> list[Page]:
    return [page for page, text in texts.items() if word in text]


def _page_links(pages: list[Page], titles: dict[Page, str]) -> str:
    return ", ".join(f'<a href="{page.href}">{html.escape(titles[page] or page.href)}</a>' for page in pages)


def build(executed_dir: Path | None = None, out_dir: Path | None = None) -> list[Path]:
    """Write the book; return the files written (sorted).  :class:`BookError` if notebooks are missing."""
    pages = collect_pages(executed_dir)
    out_dir = book_folder() if out_dir is None else out_dir
    if out_dir.exists():
        shutil.rmtree(out_dir)
    out_dir.mkdir(parents=True)
    notebooks = {page: nbformat.read(page.executed, as_version=4) for page in pages}
    titles, firsts, texts = {}, {}, {}
    for page, nb in notebooks.items():
        titles[page], firsts[page] = summary(nb)
        texts[page] = "\n".join(cell.source for cell in nb.cells if cell.cell_type == "markdown")
    solutions = {page.number: page for page in pages if page.is_solutions}
    main_pages = {page.number: page for page in pages if not page.is_solutions}

    written = []

    def write(relative: str, text: str) -> None:
        path = out_dir / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        written.append(path)

    exporter = _exporter()
    for page, nb in notebooks.items():
        depth = page.href.count("/")
        partner = (main_pages if page.is_solutions else solutions).get(page.number)
        extra = ()
        if partner is not None:
            label = "The notebook" if page.is_solutions else "Solutions"
            extra = (("../" * depth + partner.href, label),)
        title = titles[page] or page.source.stem
        write(page.href, render_notebook(nb, title, _nav(depth, extra), exporter))

    write("index.html", _page("wsn-motion", _index_body(pages, titles, firsts, notebooks, solutions)))
    write("references.html", _page("References", _references_body(texts, titles)))
    write("credits.html", _page("Credits", _credits_body(texts, titles)))
    return sorted(written)


def _index_body(pages, titles, firsts, notebooks, solutions) -> str:
    out = ["<h1>wsn-motion: tracking human motion with wireless body sensors</h1>",
           "<p>Notebooks that reproduce and extend two papers, on simulated recordings and on public real "
           "ones. Each page below is a notebook as the batch runner executed it, with its figures and "
           "tables; a notebook ends by setting its numbers beside the paper's.</p>",
           "<h2>The two questions</h2>"]
    for label, citation, question in PAPERS:
        out.append(f"<h3>{label}</h3>\n<p>{html.escape(question)}</p>\n<p><small>{citation}</small></p>")
    out += ["<h2>Which notebook answers what</h2>",
            "<table>\n<thead><tr><th>notebook</th><th>paper, sections, figures and tables</th>"
            "<th>run</th><th>solutions</th></tr></thead>\n<tbody>"]
    for page in pages:
        if page.is_solutions:
            continue
        parameters = notebooks[page].metadata.get("papermill", {}).get("parameters", {})
        run = "quick" if parameters.get("quick") else "full"
        solution = solutions.get(page.number)
        solution_link = f'<a href="{solution.href}">solutions</a>' if solution else "—"
        out.append(f'<tr><td><a href="{page.href}">{html.escape(titles[page] or page.source.stem)}</a></td>'
                   f"<td>{_markdown(firsts[page])}</td><td>{run}</td><td>{solution_link}</td></tr>")
    out.append("</tbody>\n</table>")
    out.append('<p>Sources cited across the notebooks: <a href="references.html">references</a>; data sets '
               'and their licences: <a href="credits.html">credits</a>.</p>')
    return "\n".join(out)


def _references_body(texts, titles) -> str:
    out = ["<h1>References</h1>", "<h2>The papers</h2>", "<ol>"]
    for label, citation, _ in PAPERS:
        out.append(f"<li>{label}: {citation}</li>")
    out += ["</ol>", "<h2>Methods and models cited in the notebooks and in <code>wsnlib</code></h2>", "<ul>"]
    for citation, word in REFERENCES:
        cited = _citing(texts, word)
        where = f" Cited in: {_page_links(cited, titles)}." if cited else ""
        out.append(f"<li>{citation}{where}</li>")
    out += ["</ul>", "<h2>Data sets</h2>", "<ul>"]
    for name, credit, _ in DATASETS:
        out.append(f'<li>{name}: {credit} See <a href="credits.html">credits</a>.</li>')
    out.append("</ul>")
    return "\n".join(out)


def _credits_body(texts, titles) -> str:
    out = ["<h1>Credits</h1>",
           "<p>Third-party recordings are read from a configurable folder and never committed to the "
           "project. Credit the authors wherever results from them are shown.</p>"]
    for name, credit, word in DATASETS:
        used = _citing(texts, word)
        where = f"<p>Used in: {_page_links(used, titles)}.</p>" if used else ""
        out.append(f"<h2>{name}</h2>\n<p>{credit}</p>\n{where}")
    out.append("<h2>Software</h2>\n<p>Pages rendered by nbconvert (Project Jupyter) from notebooks executed "
               "with papermill; figures drawn with matplotlib, formulas with its mathtext.</p>")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m wsnlib.book", description=__doc__.split("\n")[0])
    parser.parse_args(argv)
    try:
        written = build()
    except BookError as exc:
        print(f"make book: {exc}", file=sys.stderr)
        return 2
    print(f"Wrote {len(written)} pages to {book_folder()} (open {book_folder() / 'index.html'})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
