"""Render a report and API pages in headless Chromium and check what a reader sees; write the results as JSON.

    python tools/browser_check.py --report runs/quickstart/report.html --site site \
        --page api/evaluation/index.html --page api/control/index.html --out tools/results/browser_check.json

For each page, at a 1280 x 900 and a 800 x 900 window: whether the page scrolls sideways, tables wider than
their column (a table that scrolls inside its own box is counted apart), raw Sphinx roles in the visible text
(``:class:`...```), images wider than the page or not loaded, and API signatures wider than their box.
Chromium (``/usr/bin/chromium``, Debian's ``chromium`` package) loads a copy of each page with a small script
appended that measures the laid-out page and writes its findings into the DOM, which ``--dump-dom`` returns.
Exit code 1 when a page fails a check.
"""

from __future__ import annotations

import argparse
import json
import platform
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

CHROMIUM = "/usr/bin/chromium"
WIDTHS_PX = (1280, 800)
MARK = "harv-browser-check"

PROBE = """
<script>
window.addEventListener("load", () => {
  const vw = document.documentElement.clientWidth;
  const text = document.body.innerText;
  const tables = [...document.querySelectorAll("table")];
  const box = (el) => el.parentElement.getBoundingClientRect();
  const overflowing = tables.filter((t) => {
    const wrapper = t.parentElement;
    const scrolls = ["auto", "scroll"].includes(getComputedStyle(wrapper).overflowX);
    return !scrolls && t.getBoundingClientRect().right > box(t).right + 1;
  });
  const scrolling = tables.filter((t) => t.parentElement.scrollWidth > t.parentElement.clientWidth + 1);
  const imgs = [...document.querySelectorAll("img")];
  const sigs = [...document.querySelectorAll(".doc-signature pre, .doc-signature code")];
  const out = {
    viewport_px: vw,
    page_scrolls_sideways: document.documentElement.scrollWidth > vw + 1,
    tables: tables.length,
    tables_overflowing: overflowing.length,
    tables_scrolling_in_their_box: scrolling.length,
    raw_roles: (text.match(/:(class|func|data|mod|meth|attr|obj|exc):`/g) || []).length,
    images: imgs.length,
    images_not_loaded: imgs.filter((i) => !i.complete || i.naturalWidth === 0).length,
    images_wider_than_page: imgs.filter((i) => i.getBoundingClientRect().right > vw + 1).length,
    signatures: sigs.length,
    signatures_wider_than_box: sigs.filter((s) => s.scrollWidth > s.clientWidth + 1).length,
  };
  const pre = document.createElement("pre");
  pre.id = "MARK";
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
</script>
""".replace("MARK", MARK)


def _render(page: Path, width_px: int) -> dict:
    """The probe's findings for ``page`` (a copy with the probe appended) at ``width_px``."""
    probed = page.with_name(f".probe-{page.name}")
    html = page.read_text(encoding="utf-8")
    probed.write_text(html.replace("</body>", PROBE + "</body>"), encoding="utf-8")
    with tempfile.TemporaryDirectory() as profile:
        cmd = [
            CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            f"--user-data-dir={profile}", f"--window-size={width_px},900", "--virtual-time-budget=10000",
            "--dump-dom", probed.resolve().as_uri(),
        ]  # fmt: skip
        dom = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False).stdout
    probed.unlink()
    found = re.search(rf'<pre id="{MARK}">(.*?)</pre>', dom, re.S)
    if found is None:
        raise RuntimeError(f"the probe did not run on {page} (Chromium printed {len(dom)} characters)")
    return json.loads(found.group(1).replace("&quot;", '"'))


def _failures(r: dict) -> list[str]:
    keys = ("page_scrolls_sideways", "tables_overflowing", "raw_roles", "images_not_loaded")
    keys += ("images_wider_than_page", "signatures_wider_than_box")
    return [k for k in keys if r[k]]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--report", type=Path, action="append", default=[], help="a report.html (repeatable)")
    ap.add_argument("--site", type=Path, help="a built mkdocs site folder")
    ap.add_argument("--page", action="append", default=[], help="a page of --site, e.g. api/ppo/index.html")
    ap.add_argument("--out", type=Path, required=True, help="JSON results file")
    args = ap.parse_args(argv)
    if not Path(CHROMIUM).exists():
        print(f"browser_check: {CHROMIUM} not found (install Debian's chromium package)", file=sys.stderr)
        return 2
    version = subprocess.run([CHROMIUM, "--version"], capture_output=True, text=True).stdout.strip()
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        pages: list[tuple[str, Path]] = []
        for i, rep in enumerate(args.report):  # standalone: a copy is checked, the run folder untouched
            copy = Path(tmp) / f"report-{i}.html"
            shutil.copyfile(rep, copy)
            pages.append((str(rep), copy))
        if args.page:
            site = Path(tmp) / "site"
            shutil.copytree(args.site, site)
            pages += [(f"{args.site}/{p}", site / p) for p in args.page]
        for name, path in pages:
            for w in WIDTHS_PX:
                r = _render(path, w)
                r.update(page=name, window_px=w, failures=_failures(r))
                results.append(r)
                print(f"{name} @ {w}px: {'ok' if not r['failures'] else 'FAILS ' + ', '.join(r['failures'])}")
    command = "python tools/browser_check.py " + " ".join(sys.argv[1:] if argv is None else argv)
    doc = {"command": command, "chromium": version, "machine": platform.machine(), "pages": results}
    doc["all_pass"] = all(not r["failures"] for r in results)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=1) + "\n")
    return 0 if doc["all_pass"] else 1


if __name__ == "__main__":
    sys.exit(main())
