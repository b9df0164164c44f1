#!/usr/bin/python3
"""The web operator view served by the real daemon, looked at by Debian's headless Chromium.

  web_daemon_test.py DAEMON_BINARY OUT_DIR

Starts DAEMON_BINARY (mfcd_test_daemon: the real daemon on the simulated cell with the
ground-truth vision backend) with web.enabled on a kernel-chosen loopback port, runs pick jobs
from a Modbus client (pymodbus), then checks the JSON endpoints and the images against the
control socket's view of the same cycle, and lets Chromium load the page: the status, the
pick of the last job, its candidates and the overlay image must be shown. The screenshot is kept
as OUT_DIR/web_daemon.png. Exit 0 ok, 1 failure, 77 when chromium or pymodbus is missing.
"""
import json
import os
import sys
import tempfile
import time
import urllib.error
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from web_browser_test import Dom, check, failures, find_chromium, run  # noqa: E402
import pymodbus_client_test  # noqa: E402

# One list of failures for the checks of both helpers' modules.
pymodbus_client_test.failures = failures
pymodbus_client_test.check = check
ctl, run_job = pymodbus_client_test.ctl, pymodbus_client_test.run_job
start_daemon, stop_daemon = pymodbus_client_test.start_daemon, pymodbus_client_test.stop_daemon


def get(url):
    with urllib.request.urlopen(url, timeout=10) as r:
        return r.status, r.headers.get("Content-Type", ""), r.read()


def main():
    daemon, out_dir = sys.argv[1], sys.argv[2]
    chromium = find_chromium()
    if not chromium:
        print("SKIP: chromium is not installed (apt-get install chromium)")
        return 77
    try:
        from pymodbus.client import ModbusTcpClient
    except ImportError:
        print("SKIP: python3-pymodbus is not installed")
        return 77
    os.makedirs(out_dir, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="mfcd-web-daemon-") as tmp:
        sock = os.path.join(tmp, "ctl.sock")
        with open(os.path.join(tmp, "mfcd.yaml"), "w") as f:
            f.write(f"""daemon:
  control_socket: {sock}
  lock_memory: false
  realtime_priority: 0
camera:
  model: camera-sim.yaml
recipes:
  - {{id: 0, part: any, obj_id: 0}}
  - {{id: 1, part: breaker, obj_id: 1, mesh: parts/breaker.stl}}
  - {{id: 2, part: knob, obj_id: 5, mesh: parts/knob.stl}}
hand_eye:
  base_T_camera: {{x_mm: 500, y_mm: 0, z_mm: 800, rx_deg: 180, ry_deg: 0, rz_deg: 0}}
modbus:
  bind_address: 127.0.0.1
  port: 0
web:
  enabled: true
  bind_address: 127.0.0.1
  port: 0
snapshots:
  directory: {tmp}/snapshots
""")
        proc, status = start_daemon(daemon, tmp, sock)
        try:
            check(status is not None and status.get("state") == "ready" and "web" in status, "mfcd ready, web view listed")
            if failures:
                print(open(os.path.join(tmp, "log.txt")).read())
                return 1
            base = "http://127.0.0.1:%d" % status["web"]["port"]
            client = ModbusTcpClient("127.0.0.1", port=status["modbus"]["port"], timeout=3)
            check(client.connect(), "Modbus client connected")
            for job in (1, 2, 3):
                run_job(client, job, 1)
            ctl(sock, {"cmd": "snapshot"})
            last = ctl(sock, {"cmd": "last"})["result"]
            time.sleep(0.6)  # the main thread refreshes the view's JSON at every result and tick

            code, kind, body = get(base + "/api/last")
            web_last = json.loads(body)
            check(code == 200 and web_last.get("cycle") == last["cycle"], "/api/last is the control socket's last cycle")
            code, kind, body = get(base + "/api/status")
            check(code == 200 and json.loads(body).get("state") == "ready", "/api/status: ready")
            code, kind, body = get(base + "/api/stats")
            check(code == 200 and json.loads(body).get("cycles", 0) >= 4, "/api/stats counts the cycles")
            for name in ("ambient", "edges", "overlay"):
                try:
                    code, kind, body = get(base + "/api/image/%s.png" % name)
                except urllib.error.HTTPError as e:
                    code, kind, body = e.code, "", b""
                check(code == 200 and body.startswith(b"\x89PNG") and len(body) > 1000, "%s.png served (%d bytes)" % (name, len(body)))
            code, kind, body = get(base + "/api/snapshots")
            snaps = json.loads(body)["snapshots"]
            check(len(snaps) >= 1 and "result.json" in snaps[0]["files"], "the snapshot is listed with its files")

            with tempfile.TemporaryDirectory(prefix="mfcd-web-chromium-") as profile:
                common = [chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                          "--no-first-run", "--no-default-browser-check", "--user-data-dir=" + profile,
                          "--virtual-time-budget=5000"]
                r = run(common + ["--dump-dom", base + "/"], timeout=120)
                check(r.returncode == 0, "chromium --dump-dom exits 0")
                dom = Dom()
                dom.feed(r.stdout)
                check(dom.text.get("status-state", "").strip() == "ready", "the page shows the state")
                check(dom.attrs.get("last-cycle", {}).get("data-cycle") == str(last["cycle"]), "the page shows the last cycle")
                pick = dom.text.get("pick", "")
                check("x %.1f" % last["pick"]["x"] in pick, "the page shows the pick of the last job: %r" % pick.strip())
                check(dom.rows.get("candidates", 0) == len(last["candidates"]), "every candidate is listed")
                check(dom.attrs.get("overlay", {}).get("data-loaded") == "1", "the overlay image loaded")
                shot = os.path.join(out_dir, "web_daemon.png")
                r = run(common + ["--hide-scrollbars", "--window-size=1280,1100", "--screenshot=" + shot, base + "/"], timeout=120)
                check(r.returncode == 0 and os.path.getsize(shot) > 10000, "screenshot " + shot)
            # Nothing the browser did reached the robot link: the PLC still gets its jobs.
            regs = run_job(client, 4, 1)
            check(regs[9] == 4, "a job after the browser's visit")
            client.close()
        finally:
            code = stop_daemon(proc)
            check(code == 0, "clean exit on SIGTERM (%s)" % code)
            if failures:
                print(open(os.path.join(tmp, "log.txt")).read())
    if failures:
        print("%d check(s) failed" % len(failures))
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
