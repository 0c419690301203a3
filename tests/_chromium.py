"""Debian's headless Chromium driven by selenium, shared by the book's and JupyterLab's browser tests.

Installed by ``make browser`` (apt), never downloaded by the tests: Selenium Manager is kept
offline, and the flags keep Chromium from reaching for the network at start.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import pytest

CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
CHROMIUM_ARGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage")


@contextlib.contextmanager
def headless_chromium(profile_dir, *, window_size: str, browser_logs: bool = False):
    """A selenium Chrome driver on Debian's chromium with a fresh profile in ``profile_dir``."""
    if not (CHROMIUM.is_file() and CHROMEDRIVER.is_file()):
        pytest.fail(f"{CHROMIUM} or {CHROMEDRIVER} is missing: run `make browser` (installs Debian's chromium "
                    "and chromium-driver; needs root)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for arg in (*CHROMIUM_ARGS, f"--window-size={window_size}", f"--user-data-dir={profile_dir}"):
        options.add_argument(arg)
    if browser_logs:
        options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("SE_OFFLINE", "true")  # Selenium Manager: never fetch a browser or a driver
        chrome = webdriver.Chrome(options=options, service=Service(executable_path=str(CHROMEDRIVER)))
    chrome.set_page_load_timeout(60)
    try:
        yield chrome
    finally:
        chrome.quit()
