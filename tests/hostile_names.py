"""Results folders whose every name a report page shows is hostile: markup that would end a
<script> element, an element whose attribute runs script, an entity, quotes and a line
separator, a Plotly template, in the folder, scenario, variant and variable names, a failure's reason, a sweep's
name, axis, values and case ids. `page_tags` parses a written page as a browser does and
returns what it holds, for tests to assert that no hostile markup survived as markup."""

from __future__ import annotations

import csv
import json
from html.parser import HTMLParser
from pathlib import Path

import numpy as np

SCRIPT = "</script><script>document.title='PWN'</script>"
IMAGE = '"><img src=x onerror=alert(1)>'
ENTITY = "&lt;"
QUOTES = 'it\'s "quoted"'
SEPARATOR = "line\u2028separated\u2029here"
TEMPLATE = "50%{meta[0]}"  # a Plotly template: in a legend name or a dropdown label it would be replaced
HOSTILE = (SCRIPT, IMAGE, ENTITY, QUOTES, SEPARATOR, TEMPLATE)
REASON = "plant: " + " | ".join(HOSTILE)  # a failure's reason holding each of them

# the elements a report page is made of: a hostile name adding any other one (an <img>) fails
PAGE_TAGS = frozenset(
    "html head meta title style script body h1 h2 h3 p ul li a section div table tr th td details summary pre".split()
)


def write_trace_csv(path: Path, names: list[str], samples: int) -> None:
    """A cross-check CSV with the header `names` (every name quoted, quotes doubled)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    t = np.linspace(0.0, 1.0, samples)
    with path.open("w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream, quoting=csv.QUOTE_ALL, lineterminator="\n")
        writer.writerow(names)
        for k, time in enumerate(t):
            writer.writerow(
                [repr(float(time)), *(repr(float((j + 1) * time + 0.01 * k)) for j in range(len(names) - 1))]
            )


def write_record(folder: Path, scenario: str, variant: str, status: str, reason: str | None = None) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    record = {"scenario": scenario, "variant": variant, "status": status, "reason": reason, "warnings": list(HOSTILE)}
    (folder / "run.json").write_text(json.dumps(record))


def hostile_runs(root: Path) -> tuple[Path, Path]:
    """(results folder, references folder): a run named SCRIPT/IMAGE whose variables are the
    hostile names, one of scenario "cmp" and variant QUOTES+ENTITY with a stored reference it
    misses, one that failed before its first sample (header-only trace.csv) and one that
    failed without writing a trace, both with REASON. The results folder's name is IMAGE."""
    out = root / IMAGE
    names = ["time", "x_B", *HOSTILE]
    write_trace_csv(out / "a" / "run" / "trace.csv", names, 50)
    write_record(out / "a" / "run", SCRIPT, IMAGE, "complete")
    variant = QUOTES + ENTITY
    write_trace_csv(out / "b" / "run" / "trace.csv", names, 50)
    write_record(out / "b" / "run", "cmp", variant, "complete")
    references = root / "references"
    write_trace_csv(references / "cmp" / f"{variant}_ref.csv", names, 40)
    (out / "c" / "run").mkdir(parents=True)
    (out / "c" / "run" / "trace.csv").write_text('"' + '","'.join(name.replace('"', '""') for name in names) + '"\n')
    write_record(out / "c" / "run", SCRIPT, "empty", "failed", REASON)
    write_record(out / "d" / "run", SCRIPT, "missing", "failed", REASON)
    return out, references


def hostile_sweep(folder: Path) -> list[str]:
    """A sweep output (with kept traces) named SCRIPT over the axes SCRIPT (hostile string
    values) and IMAGE (numbers), one case failed with REASON; returns the case ids, hostile."""
    import pandas as pd

    rows, traces = [], []
    t = np.linspace(0.0, 1.0, 101)
    for index, (text, number) in enumerate((v, n) for n in (1.0, 2.0) for v in HOSTILE):
        case_id = f"{ENTITY}{index}{IMAGE}"
        failed = index == len(HOSTILE) + 1  # IMAGE and 2.0
        rows.append({"case": index, "case_id": case_id, "variant": "friction", SCRIPT: text, IMAGE: number,
                     "status": "failed" if failed else "ok", "reason": REASON if failed else None,
                     "final_error_m": 1e-4 * (index + 1), "settling_time_s": 0.2, "peak_iq_ref_A": 3.0 + index})  # fmt: skip
        traces.append(pd.DataFrame({"case_id": case_id, "time": t, "x_B": 0.1 * index * t, "iq_ref": index + 0 * t}))
    folder.mkdir(parents=True)
    pd.DataFrame(rows).to_parquet(folder / "results.parquet")
    (folder / "traces").mkdir()
    pd.concat(traces).to_parquet(folder / "traces" / "batch-000001.parquet")
    axes = {SCRIPT: list(HOSTILE), IMAGE: [1.0, 2.0]}
    (folder / "sweep.json").write_text(json.dumps({"sweep": SCRIPT, "axes": axes, "variants": ["friction"]}))
    return [row["case_id"] for row in rows]


class PageTags(HTMLParser):
    """What a page holds as a browser's parser reads it: each start tag, the text of each
    script (the first is plotly.js) and the text outside the scripts."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: list[str] = []
        self.scripts: list[str] = []
        self.text: list[str] = []
        self._in_script = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        self._in_script = tag == "script"
        if tag == "script":
            self.scripts.append("")

    def handle_endtag(self, tag: str) -> None:
        if tag == "script":
            self._in_script = False

    def handle_data(self, data: str) -> None:
        if self._in_script:
            self.scripts[-1] += data
        else:
            self.text.append(data)


def page_tags(path: Path) -> PageTags:
    """`path` parsed as a browser reads it (a <script> element ends at its first </script>)."""
    parser = PageTags()
    parser.feed(path.read_text(encoding="utf-8"))
    parser.close()
    return parser
