"""The one escaping path of the HTML report: every value from the user's files (run, scenario,
variant, folder and sweep-axis names, variable names, reasons, paths, table cells, titles) that
reaches a page goes through `page_text` or `script_json`, chosen by where it lands.

* `page_text`: text or an attribute value of the page, and every string Plotly draws (titles,
  axis titles, legend names, dropdown labels, hover text). Plotly reads those strings as a small
  markup of its own (<b>, <br>, <a href>, entities) and of templates (`%{meta[0]}` in a legend
  name or a dropdown label is replaced) and decodes the numeric entities and &amp; &lt; &gt;,
  so the one escaped form shows the name as written in both places.
* `script_json`: a value written inside a <script> element, as JSON that cannot end the element
  or start a comment there: <, >, & and U+2028/U+2029 are written as \\u escapes. Plotly writes
  its figures' data the same way but for the line separators, which `separators_escaped` adds.
* `markdown_cell`: a cell of a Markdown table (`summary.md`, a CI job summary): no raw HTML
  (<, >, & as character references), no cell boundary (| escaped) and no line break.
"""

from __future__ import annotations

import html
import json
from typing import Any

__all__ = ["markdown_cell", "page_text", "script_json", "separators_escaped"]

# Characters JSON may hold raw that are unsafe inside a <script> element, as JavaScript escapes.
_SCRIPT_ESCAPES = {"<": "\\u003c", ">": "\\u003e", "&": "\\u0026", "\u2028": "\\u2028", "\u2029": "\\u2029"}
_SCRIPT_TABLE = str.maketrans(_SCRIPT_ESCAPES)
_SEPARATORS_TABLE = str.maketrans({c: _SCRIPT_ESCAPES[c] for c in "\u2028\u2029"})
# A Markdown table cell: HTML a renderer would pass through, the cell separator, line breaks.
_MARKDOWN_TABLE = str.maketrans(
    {"&": "&amp;", "<": "&lt;", ">": "&gt;", "|": "\\|", "\n": " ", "\r": " ", "\u2028": " ", "\u2029": " "}
)


def page_text(value: Any) -> str:
    """`value` as text that shows as written in the page and in Plotly's figures: &, <, >, ", '
    and % as character references (the quote as &#34;, the form Plotly decodes as well as HTML;
    % so that no `%{...}` is read as one of Plotly's templates)."""
    return html.escape(str(value), quote=True).replace("&quot;", "&#34;").replace("%", "&#37;")


def script_json(value: Any) -> str:
    """`value` as a JavaScript literal (JSON) safe inside a <script> element: no </script>,
    <!--, ]]> or line separator can be formed by what it holds."""
    return json.dumps(value, ensure_ascii=False).translate(_SCRIPT_TABLE)


def separators_escaped(script: str) -> str:
    """`script` (Plotly's figure HTML, whose JSON escapes <, > and / but keeps U+2028/U+2029
    raw) with the line separators as \\u escapes; they occur only inside its JSON strings."""
    return script.translate(_SEPARATORS_TABLE)


def markdown_cell(value: Any) -> str:
    """`value` as the text of one Markdown table cell that shows as written: no markup a
    renderer would pass through as HTML, no `|` that would end the cell, no line break."""
    return str(value).translate(_MARKDOWN_TABLE)
