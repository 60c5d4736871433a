"""Rendering a report page in headless Chromium and reading what a reader sees (Debian's
``chromium``, installed by ``make test`` when run as root): test_rigday.py."""
import html
import json
import os
import re
import subprocess
from pathlib import Path

import pytest

CHROMIUM = os.environ.get("RIG_CHROMIUM", "/usr/bin/chromium")

# run in the page after it loaded: what the reader sees, as JSON in <pre id="render-check">
CHECK_JS = r"""
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var text = document.body.innerText;
  var verdict = document.getElementById('verdict'), tensor = document.getElementById('tensor-table');
  function rows(id) {
    var t = document.getElementById(id);
    if (!t) return null;
    return Array.prototype.map.call(t.querySelectorAll('tbody tr'), function (tr) {
      return Array.prototype.map.call(tr.cells, function (c) { return c.innerText.trim(); });
    });
  }
  var out = {
    images: imgs.length,
    loaded: imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length,
    wide: imgs.filter(function (i) {
      return i.getBoundingClientRect().right > document.documentElement.clientWidth + 1;
    }).map(function (i) { return i.getAttribute('src'); }),
    wide_tables: Array.prototype.filter.call(document.querySelectorAll('table'), function (t) {
      return t.getBoundingClientRect().right > document.documentElement.clientWidth + 1;
    }).map(function (t) { return t.id || t.className || 'table'; }),
    bad_words: text.match(/\b(nan|inf|infinity)\b/gi) || [],
    verdict: verdict ? verdict.innerText : null,
    verdict_before_tensor: !!(verdict && tensor &&
                              (verdict.compareDocumentPosition(tensor) & Node.DOCUMENT_POSITION_FOLLOWING)),
    ids: Array.prototype.map.call(document.querySelectorAll('[id]'), function (e) { return e.id; }),
    tensor: rows('tensor-table'), checks: rows('checks-table'), text: text
  };
  var pre = document.createElement('pre');
  pre.id = 'render-check';
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
"""


def chromium(args: list[str], profile: Path) -> subprocess.CompletedProcess:
    if not (os.path.isfile(CHROMIUM) and os.access(CHROMIUM, os.X_OK)):
        pytest.fail(f"{CHROMIUM} is missing: the report test renders the page in Debian's chromium "
                    "(`make setup` installs it when run as root; else `sudo apt-get install chromium`)")
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           "--disable-extensions", f"--user-data-dir={profile}", "--virtual-time-budget=5000", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def render(out: Path, work: Path) -> dict:
    """Render ``out/index.html`` in headless Chromium: the page's own check (:data:`CHECK_JS`,
    injected into a copy outside the report folder whose <base> points at it) and a screenshot
    (1200 × 2400 px, ``work/<name>.png``) that is not a blank page."""
    work.mkdir(parents=True, exist_ok=True)
    page = (out / "index.html").read_text()
    probe = work / f"{out.name}_check.html"
    probe.write_text(page.replace("<head>", f'<head><base href="{out.as_uri()}/"><script>{CHECK_JS}</script>', 1))
    dom = chromium(["--dump-dom", probe.as_uri()], work / "profile")
    assert dom.returncode == 0, dom.stderr[-2000:]
    m = re.search(r'<pre id="render-check">(.*?)</pre>', dom.stdout, re.S)
    assert m, "the page's check did not run: " + dom.stdout[:500]
    seen = json.loads(html.unescape(m.group(1)))
    shot = work / f"{out.name}.png"
    run = chromium([f"--screenshot={shot}", "--window-size=1200,2400", "--hide-scrollbars", (out / "index.html")
                    .as_uri()], work / "profile")
    assert run.returncode == 0 and shot.is_file(), run.stderr[-2000:]
    import matplotlib.image
    img = matplotlib.image.imread(shot)
    assert img.shape[:2] == (2400, 1200)
    assert (img[..., :3] < 0.5).mean() > 0.01  # text, tables and plot lines on a white page
    return seen
