"""The book in a real browser: headless Chromium on build/book/, served from 127.0.0.1.

Marked ``browser`` and deselected from the default run (pyproject ``addopts``); run it with
``make book-test`` after ``make book``.  It needs Debian's ``chromium`` and
``chromium-driver`` (``make browser`` installs them); nothing is downloaded here, and the
pages must not load anything from the network either.

Starting from ``index.html`` it opens every page reachable by internal links and fails on a
link or resource that does not answer 200, an image that did not load, or a console error.
Screenshots of the index and of the first notebook page go to ``build/book-screenshots/``.
"""

import functools
import http.server
import threading
import urllib.error
import urllib.parse
import urllib.request

import pytest
from _chromium import headless_chromium

from wsnlib import batch_selection, book, paths

pytestmark = pytest.mark.browser

_LINKS = """return {
  anchors: Array.from(document.querySelectorAll('a[href]'), a => a.href),
  loads: Array.from(document.querySelectorAll('[src], link[href]'), e => e.src || e.href),
  images: Array.from(document.images, i => [i.src.slice(0, 60), i.complete, i.naturalWidth]),
};"""


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format, *args):  # noqa: A002 (the base class's name)
        pass


@pytest.fixture(scope="module")
def site():
    """Base URL of build/book/ served by http.server on a free port of 127.0.0.1."""
    root = book.book_folder()
    if not (root / "index.html").is_file():
        pytest.fail(f"{root / 'index.html'} is missing: run `make book` first (after `make figures`)")
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(_QuietHandler, directory=root))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}/"
    server.shutdown()
    server.server_close()


@pytest.fixture(scope="module")
def driver(tmp_path_factory):
    profile = tmp_path_factory.mktemp("chromium-profile")
    with headless_chromium(profile, window_size="1280,1400", browser_logs=True) as chrome:
        yield chrome


def _status(url: str) -> int:
    try:
        with urllib.request.urlopen(url, timeout=30) as response:
            return response.status
    except urllib.error.HTTPError as exc:
        return exc.code


def test_every_page_reachable_from_the_index_loads_cleanly(site, driver):
    screenshots = paths.output_root() / "build" / "book-screenshots"
    screenshots.mkdir(parents=True, exist_ok=True)
    queue, seen, statuses, problems = ["index.html"], set(), {}, []
    notebook_shot = None
    while queue:
        page = queue.pop(0)
        if page in seen:
            continue
        seen.add(page)
        driver.get(site + page)
        found = driver.execute_script(_LINKS)
        for url in found["anchors"] + found["loads"]:
            if url.startswith(("data:", "mailto:")) or (not url.startswith(site) and url in found["anchors"]):
                continue  # embedded, or a link out of the site (not followed: the test runs offline)
            if not url.startswith(site):
                problems.append(f"{page}: loads {url} from outside the site")
                continue
            target = urllib.parse.urldefrag(url).url
            if target not in statuses:
                statuses[target] = _status(target)
            if statuses[target] != 200:
                problems.append(f"{page}: {url} answers HTTP {statuses[target]}")
            elif target.endswith(".html") and url in found["anchors"]:
                queue.append(target[len(site):])
        problems += [f"{page}: image {src}… not loaded" for src, complete, width in found["images"]
                     if not complete or width == 0]
        problems += [f"{page}: console: {entry['message']}" for entry in driver.get_log("browser")
                     if entry["level"] == "SEVERE"]
        if page == "index.html":
            driver.save_screenshot(str(screenshots / "index.png"))
        elif notebook_shot is None and page[:2].isdigit():  # the first notebook, at its first figure
            driver.execute_script("document.querySelector('.jp-OutputArea-output img')?.scrollIntoView()")
            notebook_shot = screenshots / page.replace(".html", ".png")
            driver.save_screenshot(str(notebook_shot))
    assert not problems, "\n".join(problems)
    notebooks = {f"{batch_selection.notebook_name(nb)[:-6]}.html" for nb in batch_selection.list_batch()}
    assert notebooks <= seen, f"not reachable from the index: {sorted(notebooks - seen)}"
    assert {"references.html", "credits.html"} <= seen
    assert notebook_shot is not None and notebook_shot.stat().st_size > 0
