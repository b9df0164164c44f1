#!/usr/bin/python3
"""mfcd driven by an independent Modbus/TCP client (python3-pymodbus, no code shared with mfcd).

  pymodbus_client_test.py DAEMON_BINARY

Starts DAEMON_BINARY (mfcd_test_daemon: the real daemon with the ground-truth test backend) on the
simulated cell with word order CDAB on a kernel-chosen port, learns the port from the control socket,
runs three pick jobs with the job-id handshake, and checks each pick against the simulated bin's
ground truth (from the control socket's "last"). Then map version 3: NEXT publishes the job's next
pick, a PICK_RESULT "missed" is counted and saves the job's frame set, SAVE_SCENE is a job whose
frame set is saved. Exit 0 ok, 1 failure, 77 pymodbus missing.
"""
import json
import math
import os
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time

STATUS, JOB_ECHO, ERROR_CODE, PICK_X, WORD_ORDER = 8, 9, 11, 20, 17
CANDIDATE_INDEX, PICK_RANK, PICKS_LEFT, SNAPSHOT_COUNT = 15, 50, 51, 52
NEXT, SAVE_SCENE, MISSED = 3, 4, 2
READY, DONE, PICK_VALID = 1, 1 << 2, 1 << 4
PARTS = ["breaker", "diamond", "ellipse", "tnut", "knob", "wheel"]  # config/parts/parts.csv order = obj_id

failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def ctl(path, request, timeout=30):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.settimeout(timeout)
    s.connect(path)
    s.sendall((json.dumps(request) + "\n").encode())
    data = b""
    while b"\n" not in data:
        chunk = s.recv(65536)
        if not chunk:
            break
        data += chunk
    s.close()
    return json.loads(data.split(b"\n")[0])


def to_float(first, second):  # CDAB: the lower address holds bits 15..0
    return struct.unpack(">f", struct.pack(">HH", second, first))[0]


def start_daemon(daemon, tmp, sock):
    """Starts DAEMON on tmp/mfcd.yaml in the foreground, its stderr in tmp/log.txt. Returns the
    process and its status once the control socket says ready (else the last status or None)."""
    log = open(os.path.join(tmp, "log.txt"), "w")
    proc = subprocess.Popen([daemon, "-c", os.path.join(tmp, "mfcd.yaml"), "-f"], stderr=log)
    status = None
    for _ in range(600):
        if proc.poll() is not None:
            break
        try:
            status = ctl(sock, {"cmd": "status"}, 2)
            if status.get("state") == "ready":
                break
        except OSError:
            pass
        time.sleep(0.05)
    return proc, status


def stop_daemon(proc):
    """SIGTERM, then its exit code (None when it had to be killed after 15 s)."""
    proc.send_signal(signal.SIGTERM)
    try:
        return proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        return None


def run_job(client, job, command):
    for _ in range(500):
        regs = client.read_holding_registers(0, 64, slave=1).registers
        if regs[STATUS] & READY:
            break
        time.sleep(0.01)
    wr = client.write_registers(0, [command, job, 0, 0], slave=1)
    check(not wr.isError(), f"job {job}: command {command} accepted")
    for _ in range(2000):
        regs = client.read_holding_registers(0, 64, slave=1).registers
        if regs[JOB_ECHO] == job:
            break
        time.sleep(0.01)
    check(regs[JOB_ECHO] == job, f"job {job}: echoed")
    return regs


def pick_of(regs):
    return [to_float(regs[PICK_X + 2 * i], regs[PICK_X + 2 * i + 1]) for i in range(6)]


def check_on_part(sock, job, regs):
    pick = pick_of(regs)
    last = ctl(sock, {"cmd": "last"})["result"]
    check(last["job_id"] == job, f"job {job}: control socket shows the same job")
    best = min(math.dist(pick[:3], [t["base"]["x"], t["base"]["y"], t["base"]["z"]]) for t in last["sim_truth"])
    check(best < 0.01, f"job {job}: pick {['%.2f' % v for v in pick]} is on a simulated part ({best:.4f} mm)")
    return last


def snapshot_reasons(directory):
    out = []
    for name in sorted(os.listdir(directory)) if os.path.isdir(directory) else []:
        with open(os.path.join(directory, name, "result.json")) as f:
            out.append(json.load(f).get("snapshot_reason", ""))
    return out


def wait_snapshots(client, count):
    for _ in range(500):
        regs = client.read_holding_registers(0, 64, slave=1).registers
        if regs[SNAPSHOT_COUNT] >= count:
            return regs
        time.sleep(0.01)
    return regs


def map_v3(client, sock, snapshots):
    """NEXT, PICK_RESULT and SAVE_SCENE against the real daemon (docs/register-map.md)."""
    regs = run_job(client, 34, 1)
    first = pick_of(regs)
    check(regs[PICK_RANK] == 0 and regs[PICKS_LEFT] >= 1, f"job 34: first choice, {regs[PICKS_LEFT]} more picks")
    saved = regs[SNAPSHOT_COUNT]
    wr = client.write_registers(0, [NEXT], slave=1)
    check(not wr.isError(), "NEXT accepted")
    regs = client.read_holding_registers(0, 64, slave=1).registers
    check(regs[JOB_ECHO] == 34 and regs[PICK_RANK] == 1, "NEXT: same job, pick rank 1, without waiting")
    check(math.dist(pick_of(regs)[:3], first[:3]) > 1.0, "NEXT: another part's pick")
    last = check_on_part(sock, 34, regs)
    check(last.get("pick_rank") == 1, "control socket: pick_rank 1")
    check(regs[CANDIDATE_INDEX] == last["ranked"][1], "CANDIDATE_INDEX is the second ranked candidate")

    wr = client.write_registers(4, [MISSED, 34], slave=1)
    check(not wr.isError(), "PICK_RESULT missed for job 34 accepted")
    regs = wait_snapshots(client, saved + 1)
    check(regs[SNAPSHOT_COUNT] == saved + 1, "SNAPSHOT_COUNT +1: the failed pick's frame set was saved")
    stats = ctl(sock, {"cmd": "stats"})
    check(stats["pick_results"]["missed"] == 1 and stats["next_picks"] == 1, "stats: one missed pick, one NEXT")
    check(any(r.startswith("pick result: missed (job 34, pick 2)") for r in snapshot_reasons(snapshots)),
          "a snapshot says why: pick result missed, job 34, pick 2")

    regs = run_job(client, 35, SAVE_SCENE)
    check(regs[STATUS] & DONE and regs[ERROR_CODE] == 0, "SAVE_SCENE job 35: done")
    regs = wait_snapshots(client, saved + 2)
    check(regs[SNAPSHOT_COUNT] == saved + 2, "SAVE_SCENE: SNAPSHOT_COUNT +1")
    check(snapshot_reasons(snapshots).count("requested") >= 1, "SAVE_SCENE's snapshot is there")


def main():
    try:
        from pymodbus.client import ModbusTcpClient
    except ImportError:
        print("python3-pymodbus is not installed (tools/deps/daemon.txt lists it)")
        return 77
    daemon = sys.argv[1]
    with tempfile.TemporaryDirectory(prefix="mfcd-pymodbus-") as tmp:
        sock = os.path.join(tmp, "ctl.sock")
        recipes = "\n".join(f"  - {{id: {i + 1}, part: {p}, obj_id: {i + 1}, mesh: parts/{p}.stl}}" for i, p in enumerate(PARTS))
        with open(os.path.join(tmp, "mfcd.yaml"), "w") as f:
            f.write(f"""daemon:
  control_socket: {sock}
  lock_memory: false
  realtime_priority: 0
camera:
  model: camera-sim.yaml
recipes:
  - {{id: 0, part: any, obj_id: 0}}
{recipes}
hand_eye:
  base_T_camera: {{x_mm: 500, y_mm: 0, z_mm: 800, rx_deg: 180, ry_deg: 0, rz_deg: 0}}
modbus:
  bind_address: 127.0.0.1
  port: 0
  word_order: CDAB
snapshots:
  directory: {tmp}/snapshots
""")
        proc, status = start_daemon(daemon, tmp, sock)
        try:
            check(status is not None and status.get("state") == "ready", "mfcd ready")
            if failures:
                print(open(os.path.join(tmp, "log.txt")).read())
                return 1
            port = status["modbus"]["port"]
            client = ModbusTcpClient("127.0.0.1", port=port, timeout=3)
            check(client.connect(), f"connect to 127.0.0.1:{port}")
            regs = client.read_holding_registers(0, 64, slave=1).registers
            check(regs[WORD_ORDER] == 1, "word order register says CDAB")
            major, minor, patch = (int(v) for v in status["version"].split(".")[:3])
            check(regs[53] == (major << 8 | minor) and regs[54] == patch,
                  f"registers 53..54 hold mfcd's release {status['version']}: {regs[53]:#06x} {regs[54]}")
            for job in (31, 32, 33):
                regs = run_job(client, job, 1)
                check(regs[STATUS] & DONE and regs[STATUS] & PICK_VALID and regs[ERROR_CODE] == 0,
                      f"job {job}: done, pick valid, no error")
                check_on_part(sock, job, regs)
            rr = client.write_registers(0, [1, 33, 0, 0], slave=1)
            check(rr.isError() and rr.exception_code == 3, "repeated job id -> exception 3")
            map_v3(client, sock, os.path.join(tmp, "snapshots"))
            client.close()
        finally:
            code = stop_daemon(proc)
            check(code == 0, f"clean exit on SIGTERM ({code})")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
