"""``report.html``: the report of a run, sweep or recording as one self-contained page.

The page is made from the command's ``report.md`` (one source for both: every table,
claim with its interval and verdict, and figure of the Markdown report is in the page),
with the figures embedded as ``data:`` URIs, followed by the scenario or recording file
as run, every metric (``metrics.json``; a sweep's dataset as CSV) in a ``<details>``
element (it opens without JavaScript) and the ftnav version, seed and command.  The
page has no script and loads nothing: its Content-Security-Policy (``default-src
'none'``) forbids any request, so a reference to anything outside it would show as a
console error in a browser (``tests/cli/test_html_report.py`` loads it in headless
Chromium).

The Markdown is ftnav's own (:func:`ftnav.report.summary.markdown_report`, the sweep and
recording reports): headings, paragraphs, pipe tables, bullet lists with indented
continuation lines, ``**bold**``, ```code``` and ``![alt](file)`` images; nothing else
needs converting, and every text is HTML-escaped.
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Sequence
from pathlib import Path

__all__ = ["html_report", "markdown_to_html"]

_CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'"
_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1200px; margin: 2em auto; padding: 0 1em;
       color: #222; line-height: 1.45; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.6em; text-align: right; white-space: nowrap; }
th:first-child, td:first-child { text-align: left; }
th { background: #eee; }
tr:nth-child(even) td { background: #f7f7f7; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.5em 0; }
pre { background: #f4f4f4; padding: 0.8em; overflow-x: auto; font-size: 0.85em; }
code { background: #f1f1f1; padding: 0 0.2em; }
.verdict-holds { color: #1a7f37; } .verdict-not { color: #c62828; }
.verdict-undecided { color: #9a6700; }
footer { margin-top: 3em; color: #666; font-size: 0.85em; }
"""
_IMAGE = re.compile(r"^!\[([^\]]*)\]\(([^)]+)\)$")
_MIME = {".png": "image/png", ".svg": "image/svg+xml", ".jpg": "image/jpeg"}


def _inline(text: str) -> str:
    """Escape ``text`` and turn ``**bold**`` and ```code``` into elements."""
    out = []
    for i, part in enumerate(re.split(r"(`[^`]*`)", text)):
        if i % 2:
            out.append(f"<code>{html.escape(part[1:-1])}</code>")
            continue
        esc = html.escape(part)
        esc = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", esc)
        for word, cls in (
            ("does NOT hold", "not"),
            ("DOES NOT HOLD", "not"),
            ("undecided", "undecided"),
            ("holds", "holds"),
        ):
            esc = esc.replace(
                f"<strong>{word}</strong>",
                f'<strong class="verdict-{cls}">{word}</strong>',
            )
        out.append(esc)
    return "".join(out)


def _image(alt: str, name: str, folder: Path | None) -> str:
    path = None if folder is None else folder / name
    mime = _MIME.get(Path(name).suffix.lower())
    if path is None or mime is None or not path.is_file():
        return f"<p><em>(figure {html.escape(name)} not written)</em></p>"
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return (
        f'<figure><img alt="{html.escape(alt)}" src="data:{mime};base64,{data}">'
        f"<figcaption>{html.escape(alt)}</figcaption></figure>"
    )


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def markdown_to_html(md: str, folder: Path | None = None) -> str:
    """The HTML body of ftnav's Markdown ``md`` (module docstring); images are read from
    ``folder`` and embedded."""
    lines = md.splitlines()
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.strip():
            i += 1
        elif line.startswith("#"):
            level = min(len(line) - len(line.lstrip("#")), 6)
            out.append(f"<h{level}>{_inline(line[level:].strip())}</h{level}>")
            i += 1
        elif line.startswith("|"):
            rows = []
            while i < len(lines) and lines[i].startswith("|"):
                rows.append(_cells(lines[i]))
                i += 1
            body = [r for r in rows[1:] if not all(set(c) <= set("-: ") for c in r)]
            head = "".join(f"<th>{_inline(c)}</th>" for c in rows[0])
            trs = "".join(
                "<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in r) + "</tr>" for r in body
            )
            out.append(f"<table><thead><tr>{head}</tr></thead><tbody>{trs}</tbody></table>")
        elif line.startswith("- "):
            items = []
            while i < len(lines) and lines[i].startswith("- "):
                item = [lines[i][2:]]
                i += 1
                while i < len(lines) and lines[i].startswith("  ") and lines[i].strip():
                    item.append(lines[i].strip())
                    i += 1
                items.append("<li>" + "<br>".join(_inline(x) for x in item) + "</li>")
            out.append("<ul>" + "".join(items) + "</ul>")
        elif line.startswith("```"):
            i += 1
            block = []
            while i < len(lines) and not lines[i].startswith("```"):
                block.append(lines[i])
                i += 1
            i += 1
            out.append(f"<pre>{html.escape(chr(10).join(block))}</pre>")
        elif (m := _IMAGE.match(line.strip())) is not None:
            out.append(_image(m.group(1), m.group(2), folder))
            i += 1
        else:
            para = []
            while i < len(lines) and lines[i].strip() and not lines[i].startswith(("#", "|", "- ")):
                if _IMAGE.match(lines[i].strip()):
                    break
                para.append(lines[i].strip())
                i += 1
            out.append(f"<p>{_inline(' '.join(para))}</p>")
    return "\n".join(out)


def html_report(
    md: str,
    folder: Path,
    *,
    title: str,
    sources: Sequence[tuple[str, str]] = (),
    data: tuple[str, str] | None = None,
    footer: str = "",
) -> str:
    """The self-contained page: the Markdown report ``md`` (its figures read from
    ``folder``), then each ``(heading, text)`` of ``sources`` (the scenario or recording
    file as run) as preformatted text, ``data`` = ``(file name, text)``, every metric
    (``metrics.json``, or a sweep's dataset as CSV) in a ``<details>``, then ``footer``."""
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f'<meta http-equiv="Content-Security-Policy" content="{_CSP}">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>",
        markdown_to_html(md, folder),
    ]
    for heading, text in sources:
        parts += [f"<h2>{html.escape(heading)}</h2>", f"<pre>{html.escape(text)}</pre>"]
    if data is not None:
        name, text = data
        parts += [
            f"<h2>Every metric ({html.escape(name)})</h2>",
            f"<details><summary>{html.escape(name)}</summary>",
            f"<pre>{html.escape(text)}</pre></details>",
        ]
    if footer:
        parts.append(f"<footer>{_inline(footer)}</footer>")
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"
