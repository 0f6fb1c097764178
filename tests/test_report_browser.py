"""``conesurvey report`` in a real browser: Debian's headless Chromium driven by selenium
through chromedriver. The page loads without console errors and without any network request,
every image decodes with a nonzero size, and the numbers the browser shows equal those xarray
computes from the file.

Chromium is not skipped when missing: the README's test command and ``.ci/run`` install
``chromium`` and ``chromium-driver`` (Debian packages) first.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import pytest
import xarray as xr
from look_cases import INTEGRATOR, check_numbers, run_file
from selenium import webdriver
from selenium.webdriver.chrome.service import Service

from engine import cli

CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
#: Headless, and nothing that reaches for the network on its own (docs of this machine).
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
)

ROWS_JS = """
return Array.from(document.querySelectorAll('tr')).filter(
    tr => Array.from(tr.attributes).some(a => a.name.startsWith('data-'))
).map(tr => {
    const o = {};
    for (const a of tr.attributes) if (a.name.startsWith('data-')) o[a.name] = a.value;
    for (const td of tr.querySelectorAll('td[class]'))
        o[td.className.split(' ').pop()] = td.innerText;
    return o;
});
"""

IMAGES_JS = """
return Array.from(document.images).map(i => ({
    variable: i.dataset.variable, orbit: i.closest("figure.orbit") !== null, complete: i.complete,
    width: i.naturalWidth, height: i.naturalHeight,
}));
"""


@pytest.fixture(scope="module")
def browser():
    for exe in (CHROMIUM, CHROMEDRIVER):
        if not exe.exists():
            pytest.fail(
                f"{exe} is missing: apt-get install -y chromium chromium-driver "
                "(the README's test command and .ci/run install them)"
            )
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in FLAGS:
        options.add_argument(flag)
    with tempfile.TemporaryDirectory(prefix="chromium-profile-") as profile:
        options.add_argument(f"--user-data-dir={profile}")
        options.add_argument("--window-size=1280,1600")
        options.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
        driver = webdriver.Chrome(options=options, service=Service(str(CHROMEDRIVER)))
        try:
            yield driver
        finally:
            driver.quit()


def _requests(driver) -> list[str]:
    """URLs the page requested (from the DevTools performance log)."""
    urls = []
    for entry in driver.get_log("performance"):
        msg = json.loads(entry["message"])["message"]
        if msg.get("method") == "Network.requestWillBeSent":
            urls.append(msg["params"]["request"]["url"])
    return urls


def test_console_errors_are_seen(browser):
    """The log the next test relies on does catch a console error."""
    browser.get("data:text/html,<p>x</p><script>console.error('boom')</script>")
    assert any("boom" in e["message"] for e in browser.get_log("browser") if e["level"] == "SEVERE")


def test_report_in_chromium(browser, tmp_path):
    t0 = time.perf_counter()
    nc = run_file(INTEGRATOR, tmp_path / "rk.nc")
    page = tmp_path / "report.html"
    assert cli.main(["report", str(nc), "-o", str(page)]) == 0
    t1 = time.perf_counter()
    browser.get_log("browser")  # drop what earlier pages logged
    browser.get_log("performance")
    browser.get(page.as_uri())
    assert browser.execute_script("return document.readyState") == "complete"

    errors = [e for e in browser.get_log("browser") if e["level"] in ("SEVERE", "WARNING")]
    assert errors == []
    requests = _requests(browser)
    assert requests and all(u.startswith(("file:", "data:")) for u in requests), requests
    assert browser.execute_script("return document.scripts.length") == 0

    ds = xr.open_dataset(nc)
    assert browser.title.startswith(ds.attrs["title"])  # shown as text, not run as a script
    images = browser.execute_script(IMAGES_JS)
    maps = [i for i in images if not i["orbit"]]  # one map per variable, then sample orbits
    assert sorted(i["variable"] for i in maps) == sorted(ds.data_vars)
    assert all(i["variable"] is None for i in images if i["orbit"])
    for img in images:
        assert img["complete"] and img["width"] > 0 and img["height"] > 0, img

    rows = browser.execute_script(ROWS_JS)
    n_flags = sum(len(ds[v].attrs["flag_meanings"].split()) for v in ("orbit_class", "status"))
    assert check_numbers(rows, nc) == n_flags + len(ds.data_vars) - 2

    shot = tmp_path / "report.png"
    assert browser.save_screenshot(str(shot))
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 20_000
    t2 = time.perf_counter()
    print(f"report written in {t1 - t0:.1f} s, checked in Chromium in {t2 - t1:.1f} s")
