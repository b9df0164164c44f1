#!/usr/bin/python3
"""The web operator view (web/) in a real browser: Debian's Chromium, headless.

  web_browser_test.py DEMO_BINARY WEB_ROOT OUT_DIR

Starts DEMO_BINARY (tests/daemon/web_demo_main.cpp: WebServer with canned data whose cycle changes
every second; here every 50 ms, because Chromium's virtual time runs the page's five one-second
polls in about a second) on a kernel-chosen loopback port, lets headless Chromium run the page for
five seconds of virtual time and dump the DOM, and checks that it shows the status state, a pick,
candidates, the time plot with several cycles and the images loaded for a cycle (app.js sets
data-loaded="1" and data-cycle on the img's load). Then takes a 1280x900 screenshot, kept as
OUT_DIR/web_view.png (non-empty PNG checked), and the dumped DOM as OUT_DIR/web_view.html.
Exit 0 ok, 1 failure, 77 when chromium is not installed.
"""
import html.parser
import os
import shutil
import subprocess
import sys
import tempfile
import threading

failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def find_chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


class Dom(html.parser.HTMLParser):
    """Elements by id: attributes and the text inside them."""

    def __init__(self):
        super().__init__()
        self.attrs = {}   # id -> {attr: value}
        self.text = {}    # id -> text content
        self.open = []    # ids of the open elements (None for elements without one)
        self.rows = {}    # table id -> number of <tr> in its <tbody>
        self.table = None
        self.in_tbody = False

    VOID = {"img", "br", "hr", "meta", "link", "input", "source", "area", "base", "col", "embed", "wbr"}

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        ident = a.get("id")
        if ident:
            self.attrs[ident] = a
            self.text.setdefault(ident, "")
        if tag == "table":
            self.table = ident
        elif tag == "tbody":
            self.in_tbody = True
        elif tag == "tr" and self.in_tbody and self.table:
            self.rows[self.table] = self.rows.get(self.table, 0) + 1
        if tag not in self.VOID:
            self.open.append(ident)

    def handle_endtag(self, tag):
        if tag == "tbody":
            self.in_tbody = False
        elif tag == "table":
            self.table = None
        if tag not in self.VOID and self.open:
            self.open.pop()

    def handle_data(self, data):
        for ident in self.open:
            if ident:
                self.text[ident] += data


def run(cmd, timeout):
    print("$ " + " ".join(cmd), flush=True)
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=timeout, text=True)


def main():
    if len(sys.argv) != 4:
        print(__doc__)
        return 2
    demo, web_root, out_dir = sys.argv[1:]
    chromium = find_chromium()
    if not chromium:
        print("SKIP: chromium is not installed (apt-get install chromium)")
        return 77
    os.makedirs(out_dir, exist_ok=True)

    proc = subprocess.Popen([demo, "--web-root", web_root, "--cycle-ms", "50"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        line = [None]
        reader = threading.Thread(target=lambda: line.__setitem__(0, proc.stdout.readline()), daemon=True)
        reader.start()
        reader.join(20)
        if not line[0] or not line[0].startswith("PORT "):
            print("FAIL the demo server did not report its port: %r" % line[0])
            return 1
        url = "http://127.0.0.1:%d/" % int(line[0].split()[1])
        print("serving " + url, flush=True)

        with tempfile.TemporaryDirectory(prefix="mfcd-web-chromium-") as profile:
            common = [chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                      "--no-first-run", "--no-default-browser-check", "--user-data-dir=" + profile,
                      "--virtual-time-budget=5000"]

            # --enable-logging=stderr: the page's console messages, so a script error is seen.
            r = run(common + ["--enable-logging=stderr", "--v=0", "--dump-dom", url], timeout=120)
            check(r.returncode == 0, "chromium --dump-dom exits 0 (%d)" % r.returncode)
            if r.returncode != 0:
                print(r.stderr[-3000:])
            console = [l for l in r.stderr.splitlines() if ":CONSOLE" in l]
            for l in console:
                print("  console: " + l)
            check(not any("Uncaught" in l or "Error" in l for l in console), "no script errors on the console")
            check(" Content Security Policy" not in r.stderr, "nothing blocked by the page's Content-Security-Policy")
            dom = Dom()
            dom.feed(r.stdout)
            with open(os.path.join(out_dir, "web_view.html"), "w") as f:
                f.write(r.stdout)

            state = dom.text.get("status-state", "").strip()
            check(state == "ready", "status state is shown: %r" % state)
            check(dom.text.get("status-camera", "").strip().startswith("simulated"), "camera is shown")
            check(dom.text.get("status-modbus-clients", "").strip() == "1", "Modbus clients are shown")
            cycle = dom.attrs.get("last-cycle", {}).get("data-cycle", "")
            check(cycle.isdigit() and int(cycle) >= 1, "the last cycle is shown: %r" % cycle)
            pick = dom.text.get("pick", "")
            pick_cls = dom.attrs.get("pick", {}).get("class", "")
            check("none" not in pick_cls.split() and "x 4" in pick and "score" in pick, "a pick is shown: %r" % pick)
            check(dom.rows.get("candidates", 0) == 4, "four candidates: %d rows" % dom.rows.get("candidates", 0))
            check("★ chosen" in dom.text.get("candidates", ""), "the chosen candidate is marked")
            overlay = dom.attrs.get("overlay", {})
            src = overlay.get("src", "")
            check(src.startswith("/api/image/overlay.png?cycle="), "overlay img has a src: %r" % src)
            check(overlay.get("data-loaded") == "1", "overlay image loaded (data-loaded=%r)" % overlay.get("data-loaded"))
            check(src.endswith("?cycle=" + overlay.get("data-cycle", "-")), "the loaded overlay is the one asked for: %r" % src)
            for name in ("ambient", "edges"):
                check(dom.attrs.get(name, {}).get("data-loaded") == "1", name + " image loaded")
            points = dom.attrs.get("cycle-plot", {}).get("data-points", "0")
            check(points.isdigit() and int(points) >= 2, "the time plot has several cycles: %r" % points)
            check("101.0" in dom.text.get("stats-percentiles", ""), "percentiles are shown")
            check(dom.rows.get("recipes-table", 0) == 6, "six recipes")
            snaps = dom.text.get("snapshot-list", "")
            check("cycle3" in snaps and "overlay.png" in snaps, "snapshots with their files are listed")
            check('"active": false' in dom.text.get("calibration-state", ""), "calibration state is shown")
            check("conn-ok" in dom.attrs.get("conn", {}).get("class", ""), "the page reports a live connection")

            shot = os.path.join(out_dir, "web_view.png")
            if os.path.exists(shot):
                os.remove(shot)
            r = run(common + ["--hide-scrollbars", "--window-size=1280,900", "--screenshot=" + shot, url], timeout=120)
            check(r.returncode == 0, "chromium --screenshot exits 0 (%d)" % r.returncode)
            if r.returncode != 0:
                print(r.stderr[-3000:])
            ok = False
            if os.path.exists(shot):
                with open(shot, "rb") as f:
                    head = f.read(24)
                size = os.path.getsize(shot)
                width = int.from_bytes(head[16:20], "big") if len(head) == 24 else 0
                height = int.from_bytes(head[20:24], "big") if len(head) == 24 else 0
                ok = head.startswith(b"\x89PNG\r\n\x1a\n") and size > 10000
                print("screenshot %s: %d bytes, %dx%d" % (shot, size, width, height))
            check(ok, "the screenshot is a non-empty PNG")
    finally:
        proc.stdin.close()  # the demo stops when its stdin closes
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            failures.append("the demo server did not stop when its stdin closed")
    check(proc.returncode == 0, "the demo server exits 0 (%s)" % proc.returncode)

    if failures:
        print("%d check(s) failed" % len(failures))
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
