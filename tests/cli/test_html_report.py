"""``report.html`` (issue 23 item 6) in a real browser: Debian's headless Chromium.

Oracles: the browser itself.  The page, served on 127.0.0.1, is framed by a checking
page of the same origin that counts what the browser rendered (tables, their rows, images
decoded); Chromium's console log (``--enable-logging=stderr``) must hold no message from
the report (it has no script, and its Content-Security-Policy turns any request for
something outside the page into a console error: the control page shows the log catches
one).  With scripts disabled the report still shows its tables and every metric.  The
Markdown-to-HTML conversion is checked against the report.md it is made from.

Chromium is installed by ``make test`` (``make browser``); where it is not, the browser
tests are skipped with the reason.
"""

from __future__ import annotations

import functools
import html
import http.server
import json
import re
import shutil
import subprocess
import threading
from pathlib import Path

import pytest
from seed000_copy import seed000_copy

from ftnav.cli import main
from ftnav.report.html import markdown_to_html

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
browser = pytest.mark.skipif(
    CHROMIUM is None, reason="no chromium (make browser installs Debian's, as root with apt)"
)

CHECK = """<!DOCTYPE html><html><body><pre id="result">pending</pre>
<iframe id="f" src="{page}" width="1200" height="800"></iframe>
<script>
document.getElementById('f').addEventListener('load', () => {{
  const d = document.getElementById('f').contentDocument;
  const imgs = Array.from(d.images);
  document.getElementById('result').textContent = JSON.stringify({{
    tables: d.querySelectorAll('table').length,
    rows: d.querySelectorAll('tbody tr').length,
    images: imgs.length,
    decoded: imgs.filter(i => i.complete && i.naturalWidth > 0).length,
    text: d.body.innerText,
  }});
}});
</script></body></html>
"""
BAD = (
    '<!DOCTYPE html><html><head><meta http-equiv="Content-Security-Policy" '
    "content=\"default-src 'none'; img-src data:\"></head><body>"
    '<img src="http://203.0.113.1/x.png"></body></html>'
)


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    root = tmp_path_factory.mktemp("html")
    sc = seed000_copy(root / "small.toml", ("ckf", "fkf-inverse-trace-chi2"), steps=400)
    args = ["run", str(sc), "--runs", "3", "--out", str(root / "run"), "--quiet"]
    assert main([*args, "--workers", "1"]) == 0
    sweep = ["sweep", str(sc), "--set", "faults.0.magnitude=10,40", "--runs", "2", "--quiet"]
    assert main([*sweep, "--out", str(root / "sweep"), "--workers", "1"]) == 0
    return root


@pytest.fixture(scope="module")
def server(reports):
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(reports))
    handler.log_message = lambda *a, **k: None  # type: ignore[attr-defined]
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    t = threading.Thread(target=httpd.serve_forever, daemon=True)
    t.start()
    yield reports, f"http://127.0.0.1:{httpd.server_address[1]}"
    httpd.shutdown()


def _chromium(url: str, profile: Path, *extra: str) -> tuple[str, str]:
    assert CHROMIUM is not None
    flags = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={profile}",
        "--enable-logging=stderr",
        "--v=0",
        "--virtual-time-budget=10000",
    ]
    done = subprocess.run(
        [
            CHROMIUM,
            *flags,
            *extra,
            *([] if any("screenshot" in e for e in extra) else ["--dump-dom"]),
            url,
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    return done.stdout, done.stderr


def _rendered(server, page: str, tmp_path: Path) -> tuple[dict, list[str]]:
    root, base = server
    check = root / f"check-{page.replace('/', '-')}"
    check.write_text(CHECK.format(page=f"/{page}"))
    dom, log = _chromium(f"{base}/{check.name}", tmp_path / "profile")
    m = re.search(r'<pre id="result">(.*?)</pre>', dom, flags=re.S)
    assert m is not None, dom[:500]
    got = json.loads(html.unescape(m.group(1)))
    console = [line for line in log.splitlines() if "CONSOLE" in line]
    return got, console


@browser
@pytest.mark.parametrize("kind", ["run", "sweep"])
def test_the_report_loads_without_console_errors_and_shows_tables_and_figures(
    server, kind, tmp_path
):
    root, _ = server
    md = (root / kind / "report.md").read_text()
    figures = re.findall(r"^!\[[^\]]*\]\(([^)]+)\)$", md, flags=re.M)
    table_rows = [ln for ln in md.splitlines() if ln.startswith("|")]
    got, console = _rendered(server, f"{kind}/report.html", tmp_path)
    assert console == []
    assert got["tables"] >= 1 and got["rows"] >= 1
    # every row of every Markdown table (less the header and rule lines) is shown
    assert got["rows"] == len(table_rows) - 2 * md.count("\n|---")
    assert figures and got["images"] == len(figures) == got["decoded"]
    text = got["text"]
    data = "metrics.json" if kind == "run" else "sweep.nc"
    assert f"Every metric ({data})" in text and "root seed 1" in text
    if kind == "run":
        assert "Claims checked" not in md or "interval" in text  # claims with intervals
        assert "Scenario as run: small.toml" in text


@browser
def test_the_console_check_catches_a_request_outside_the_page(server, tmp_path):
    root, _ = server
    (root / "bad.html").write_text(BAD)
    _, console = _rendered(server, "bad.html", tmp_path)
    assert any("Content Security Policy" in line for line in console)


@browser
def test_without_javascript_the_page_renders(reports, tmp_path):
    from matplotlib.image import imread

    page = (reports / "run" / "report.html").as_uri()
    shot = tmp_path / "shot.png"
    _chromium(
        page,
        tmp_path / "profile",
        "--disable-javascript",
        "--window-size=1000,1500",
        f"--screenshot={shot}",
    )
    ink = imread(shot)[..., :3].mean(-1) < 0.8  # text, rules and figure lines
    assert ink.mean() > 0.02  # a blank or unstyled-error page has almost none


def test_the_page_is_self_contained_and_holds_what_report_md_holds(reports):
    page = (reports / "run" / "report.html").read_text()
    md = (reports / "run" / "report.md").read_text()
    assert "<script" not in page and "http://" not in page and "https://" not in page
    assert page.count("data:image/png;base64,") == md.count("![")
    assert page.count("<tr>") - page.count("<thead>") == sum(
        1 for ln in md.splitlines() if ln.startswith("|") and not ln.startswith("|---")
    ) - md.count("\n|---")
    block = re.search(r"<details>.*?<pre>(.*?)</pre>", page, flags=re.S)
    assert block is not None
    assert json.loads(html.unescape(block.group(1))) == json.loads(
        (reports / "run" / "metrics.json").read_text()
    )


def test_markdown_conversion_escapes_and_keeps_structure():
    body = markdown_to_html(
        "# T <x>\n\npara **b** `c<d>`\n\n| a | b |\n|---|---|\n| 1 | <2> |\n\n"
        "- item **holds**\n  more\n\n![missing](nope.png)\n"
    )
    assert "<h1>T &lt;x&gt;</h1>" in body
    assert "<p>para <strong>b</strong> <code>c&lt;d&gt;</code></p>" in body
    assert "<td>&lt;2&gt;</td>" in body and body.count("<tr>") == 2
    assert '<li>item <strong class="verdict-holds">holds</strong><br>more</li>' in body
    assert "figure nope.png not written" in body
