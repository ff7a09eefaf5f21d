"""A Markdown report as one self-contained HTML page (figures embedded as base64 data URIs).

A small renderer for the Markdown the toolbox's reports use, with no dependency: ATX headings
(``#`` to ``######``), paragraphs, ``-``/``*`` bullet lists, pipe tables (a header row, a
``|---|`` rule, body rows), fenced code blocks, and inline ``**bold**``, ``*italic*``,
```code```, ``[text](url)`` and ``![alt](file.png)``. Every other character is escaped, so
the page shows the report's text as written. Images whose file lies beside the report are
read and embedded, so the page opens anywhere on its own; a missing image file raises.

Examples
--------
>>> page = markdown_to_html("# Title\\n\\nSome **bold** text.\\n\\n| a | b |\\n|---|---|\\n| 1 | 2 |\\n")
>>> "<h1>Title</h1>" in page, "<strong>bold</strong>" in page, "<td>2</td>" in page
(True, True, True)
"""

from __future__ import annotations

import base64
import html
import mimetypes
import re
from pathlib import Path

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["markdown_to_html", "PAGE_STYLE"]

#: CSS of the page: readable width, tables with borders, figures scaled to the page.
PAGE_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; line-height: 1.45;
       max-width: 1200px; margin: 2em auto; padding: 0 1em; color: #222; }
h1, h2, h3 { line-height: 1.2; } h2 { border-bottom: 1px solid #ddd; padding-bottom: 0.2em; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; display: block; overflow-x: auto; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; white-space: nowrap; }
th { background: #f3f3f3; } td:first-child, th:first-child { text-align: left; }
code { background: #f5f5f5; padding: 0 0.2em; border-radius: 3px; }
pre { background: #f5f5f5; padding: 0.6em; overflow-x: auto; }
img { max-width: 100%; height: auto; display: block; margin: 0.5em 0; }
"""

_INLINE = re.compile(r"(!?)\[([^\]]*)\]\(([^)\s]+)\)|\*\*(.+?)\*\*|`([^`]+)`|(?<![\w*])\*([^*\s][^*]*?)\*(?!\w)")


def _data_uri(path: Path) -> str:
    kind = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
    return f"data:{kind};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def _inline(text: str, base: Path | None) -> str:
    """Escape ``text`` and render its inline constructs."""
    out, pos = [], 0
    for m in _INLINE.finditer(text):
        out.append(html.escape(text[pos:m.start()], quote=False))
        bang, label, url, bold, code, italic = m.groups()
        if url is not None and bang:
            src = url
            if base is not None and "://" not in url and not url.startswith("data:"):
                file = base / url
                if not file.is_file():
                    raise ParameterError(f"image {url!r} of the report is missing: no file {file}")
                src = _data_uri(file)
            out.append(f'<img src="{html.escape(src)}" alt="{html.escape(label)}">')
        elif url is not None:
            out.append(f'<a href="{html.escape(url)}">{_inline(label, base)}</a>')
        elif bold is not None:
            out.append(f"<strong>{_inline(bold, base)}</strong>")
        elif code is not None:
            out.append(f"<code>{html.escape(code, quote=False)}</code>")
        else:
            out.append(f"<em>{_inline(italic, base)}</em>")
        pos = m.end()
    out.append(html.escape(text[pos:], quote=False))
    return "".join(out)


def _cells(line: str) -> list:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def _is_rule(line: str) -> bool:
    return bool(re.fullmatch(r"\|?\s*:?-{3,}:?\s*(\|\s*:?-{3,}:?\s*)*\|?", line.strip()))


def _body(lines: list, base: Path | None) -> list:
    out, i, para = [], 0, []

    def flush():
        if para:
            out.append("<p>" + _inline(" ".join(s.strip() for s in para), base) + "</p>")
            para.clear()

    while i < len(lines):
        line = lines[i]
        stripped = line.strip()
        heading = re.match(r"^(#{1,6})\s+(.*?)\s*#*\s*$", line)
        if not stripped:
            flush()
            i += 1
        elif stripped.startswith("```"):
            flush()
            j = i + 1
            while j < len(lines) and not lines[j].strip().startswith("```"):
                j += 1
            out.append("<pre><code>" + html.escape("\n".join(lines[i + 1:j]), quote=False) + "</code></pre>")
            i = j + 1
        elif heading:
            flush()
            n = len(heading.group(1))
            out.append(f"<h{n}>{_inline(heading.group(2), base)}</h{n}>")
            i += 1
        elif stripped.startswith("|") and i + 1 < len(lines) and _is_rule(lines[i + 1]):
            flush()
            rows = ["<table>", "<thead><tr>" + "".join(f"<th>{_inline(c, base)}</th>" for c in _cells(line))
                    + "</tr></thead>", "<tbody>"]
            i += 2
            while i < len(lines) and lines[i].strip().startswith("|"):
                rows.append("<tr>" + "".join(f"<td>{_inline(c, base)}</td>" for c in _cells(lines[i])) + "</tr>")
                i += 1
            out += rows + ["</tbody>", "</table>"]
        elif re.match(r"^\s*[-*]\s+", line):
            flush()
            items = []
            while i < len(lines) and (re.match(r"^\s*[-*]\s+", lines[i])
                                      or (items and lines[i].startswith("  ") and lines[i].strip())):
                if re.match(r"^\s*[-*]\s+", lines[i]):
                    items.append(re.sub(r"^\s*[-*]\s+", "", lines[i]))
                else:
                    items[-1] += " " + lines[i].strip()
                i += 1
            out += ["<ul>"] + [f"<li>{_inline(it, base)}</li>" for it in items] + ["</ul>"]
        else:
            para.append(line)
            i += 1
    flush()
    return out


def markdown_to_html(text: str, base_dir=None, title: str | None = None) -> str:
    """Render Markdown (the report subset) as one self-contained HTML page.

    Parameters
    ----------
    text : str
        The Markdown.
    base_dir : str or Path, optional
        Folder the image paths are relative to; their files are embedded as base64 data URIs
        (default: image links are kept as they are).
    title : str, optional
        The page's ``<title>`` (default: the first heading, else ``"report"``).

    Returns
    -------
    str
        A complete HTML5 document.
    """
    if not isinstance(text, str):
        raise ParameterError(f"text must be a str, got {type(text).__name__}")
    base = Path(base_dir) if base_dir is not None else None
    lines = text.splitlines()
    if title is None:
        first = next((ln for ln in lines if ln.startswith("#")), "# report")
        title = first.lstrip("#").strip()
    body = "\n".join(_body(lines, base))
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
            f"<title>{html.escape(title)}</title>\n<style>{PAGE_STYLE}</style>\n</head>\n<body>\n"
            f"{body}\n</body>\n</html>\n")
