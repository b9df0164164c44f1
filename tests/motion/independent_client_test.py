#!/usr/bin/python3
"""The robot-link Modbus server driven by clients that share no code with it.

  independent_client_test.py SERVER_BINARY pymodbus   -- python3-pymodbus client
  independent_client_test.py SERVER_BINARY mbpoll     -- mbpoll command-line client

Starts the loopback test server (tests/motion/modbus_sim_server.cpp), which has a simulated
daemon behind it. Exit 0 on success, 1 on failure, 77 when the client is not installed.
"""
import shutil
import struct
import subprocess
import sys
import time

STATUS, JOB_ECHO, PICK_X, SCORE, TEST_VECTOR, WORD_ORDER, MAP_VERSION = 8, 9, 20, 32, 34, 17, 18
DONE, PICK_VALID, LOOK_WANTED = 1 << 2, 1 << 4, 1 << 6
PICK_RANK, PICKS_LEFT, NEXT = 50, 51, 3
LOOK_REASON, LOOK_X, LOOK = 55, 56, 5
GRIP_STATE, GRIP_OF_JOB, GRIP_X, CHECK_GRIP = 68, 69, 70, 6
EXPECTED, POSE_ERROR, NOT_GRASPED = 1, 2, 3
BLOCK = 96  # registers 0..95: the whole map (map version 5)
SIM_LOOK_RECIPE = 90  # recipe 90 + k: the result asks for a second look for reason k
SIM_GRIP_RECIPE = 80  # CHECK_GRIP with recipe 82: pose error, 83: not grasped, any other: expected


def pick_for_job(job):  # tests/motion/sim_daemon.hpp
    return [100.0 + job, -250.5, 42.25, 180.0, -0.5, float(job % 360) - 90.0]


def look_pose_for_job(job):  # tests/motion/sim_daemon.hpp
    return [300.0 + job, -120.25, 615.5, 179.5, -12.75, float(job % 180) - 45.0]


def grip_pose_for_job(job):  # tests/motion/sim_daemon.hpp: tool_T_part of the checked job's part
    return [1.5, -0.75, 148.0 + job % 16, 0.25, -0.5, float(job % 90)]


def sim_grip_errors(state):  # tests/motion/sim_daemon.hpp: translation mm, rotation degrees
    return [6.25, 4.5] if state == POSE_ERROR else [0.5, 0.25]


def to_float(first, second, order):
    high, low = (first, second) if order == "ABCD" else (second, first)
    return struct.unpack(">f", struct.pack(">HH", high, low))[0]


class Server:
    def __init__(self, binary, order):
        self.proc = subprocess.Popen([binary, order], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline().split()
        if len(line) != 2 or line[0] != "PORT":
            raise RuntimeError(f"server did not report its port: {line}")
        self.port = int(line[1])

    def close(self):
        self.proc.stdin.close()
        self.proc.wait(timeout=10)
        if self.proc.returncode != 0:
            raise RuntimeError(f"server exited with {self.proc.returncode}")


failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        failures.append(what)


def run_pymodbus(binary):
    try:
        from pymodbus.client import ModbusTcpClient
    except ImportError:
        print("python3-pymodbus is not installed (tools/deps/motion.txt lists it)")
        sys.exit(77)
    for order in ("ABCD", "CDAB"):
        server = Server(binary, order)
        client = ModbusTcpClient("127.0.0.1", port=server.port, timeout=3)
        check(client.connect(), f"{order}: connect")
        rr = client.read_holding_registers(0, BLOCK, slave=1)
        check(not rr.isError() and len(rr.registers) == BLOCK, f"{order}: whole map in one read of {BLOCK}")
        regs = rr.registers
        check(regs[MAP_VERSION] == 5, f"{order}: map version 5")
        for count, version in ((80, 4), (64, 3)):
            rr = client.read_holding_registers(0, count, slave=1)
            check(not rr.isError() and len(rr.registers) == count,
                  f"{order}: a read of {count} (map version {version}) still works")
        expect = [0x47F1, 0x2000] if order == "ABCD" else [0x2000, 0x47F1]
        check(regs[TEST_VECTOR:TEST_VECTOR + 2] == expect, f"{order}: test vector registers {expect}")
        check(regs[WORD_ORDER] == (0 if order == "ABCD" else 1), f"{order}: word order register")
        check(to_float(*regs[TEST_VECTOR:TEST_VECTOR + 2], order) == 123456.0, f"{order}: test vector decodes")

        # Job-id handshake: TRIGGER job 21, recipe 3, mode 0 in one write; wait for the echo.
        wr = client.write_registers(0, [1, 21, 3, 0], slave=1)
        check(not wr.isError(), f"{order}: trigger accepted")
        regs = wait_for_echo(client, 21)
        check(regs[JOB_ECHO] == 21, f"{order}: job id echoed")
        check(regs[STATUS] & DONE and regs[STATUS] & PICK_VALID, f"{order}: done and pick valid")
        pose = [to_float(regs[PICK_X + 2 * i], regs[PICK_X + 2 * i + 1], order) for i in range(6)]
        check(pose == pick_for_job(21), f"{order}: pick {pose}")
        check(to_float(regs[SCORE], regs[SCORE + 1], order) == 0.875, f"{order}: score")

        rr = client.read_holding_registers(BLOCK - 1, 2, slave=1)
        check(rr.isError() and rr.exception_code == 2, f"{order}: read past the map -> exception 2")
        rr = client.write_register(STATUS, 1, slave=1)
        check(rr.isError() and rr.exception_code == 2, f"{order}: write to status -> exception 2")
        rr = client.write_registers(0, [1, 21, 3, 0], slave=1)
        check(rr.isError() and rr.exception_code == 3, f"{order}: repeated job id -> exception 3")
        rr = client.read_coils(0, 1, slave=1)
        check(rr.isError() and rr.exception_code == 1, f"{order}: read coils -> exception 1")
        rr = client.readwrite_registers(read_address=TEST_VECTOR, read_count=2, write_address=1,
                                        write_registers=[22, 3], slave=1)
        check(not rr.isError() and rr.registers == expect, f"{order}: FC 0x17 read/write")
        pymodbus_second_look(client, order)
        pymodbus_gripper_check(client, order)
        client.close()
        server.close()


def wait_for_echo(client, job):
    regs = None
    for _ in range(300):
        regs = client.read_holding_registers(0, BLOCK, slave=1).registers
        if regs[JOB_ECHO] == job:
            break
        time.sleep(0.01)
    return regs


def pymodbus_second_look(client, order):
    """TRIGGER answered with LOOK_WANTED, then LOOK (map version 4)."""
    wr = client.write_registers(0, [1, 23, SIM_LOOK_RECIPE + 2, 0], slave=1)
    check(not wr.isError(), f"{order}: trigger job 23 (second look wanted) accepted")
    regs = wait_for_echo(client, 23)
    check(regs[JOB_ECHO] == 23 and regs[STATUS] & LOOK_WANTED and not regs[STATUS] & PICK_VALID,
          f"{order}: job 23: LOOK_WANTED, no pick: status {regs[STATUS]:#06x}")
    check(regs[LOOK_REASON] == 2, f"{order}: LOOK_REASON 2 (ambiguous)")
    pose = [to_float(regs[LOOK_X + 2 * i], regs[LOOK_X + 2 * i + 1], order) for i in range(6)]
    check(pose == look_pose_for_job(23), f"{order}: look pose {pose}")
    rr = client.write_registers(0, [NEXT], slave=1)
    check(rr.isError() and rr.exception_code == 3, f"{order}: NEXT on a second-look result -> exception 3")

    wr = client.write_registers(0, [LOOK, 24, SIM_LOOK_RECIPE + 2, 0], slave=1)
    check(not wr.isError(), f"{order}: LOOK job 24 accepted")
    regs = wait_for_echo(client, 24)
    check(regs[STATUS] & DONE and regs[STATUS] & PICK_VALID and not regs[STATUS] & LOOK_WANTED,
          f"{order}: LOOK job 24: done with a pick: status {regs[STATUS]:#06x}")
    check(regs[LOOK_REASON:LOOK_X + 12] == [0] * 13, f"{order}: registers 55..67 read 0 without LOOK_WANTED")
    pose = [to_float(regs[PICK_X + 2 * i], regs[PICK_X + 2 * i + 1], order) for i in range(6)]
    check(pose == pick_for_job(24), f"{order}: LOOK job 24's pick {pose}")
    rr = client.write_registers(0, [LOOK, 25, SIM_LOOK_RECIPE + 2, 0], slave=1)
    check(rr.isError() and rr.exception_code == 3, f"{order}: LOOK without LOOK_WANTED -> exception 3")


def grip_floats(regs, order):
    return [to_float(regs[GRIP_X + 2 * i], regs[GRIP_X + 2 * i + 1], order) for i in range(8)]


def pymodbus_gripper_check(client, order):
    """CHECK_GRIP on the pick in the registers, in each of its three outcomes (map version 5)."""
    wr = client.write_registers(0, [CHECK_GRIP, 25, SIM_GRIP_RECIPE + 2, 0], slave=1)
    check(not wr.isError(), f"{order}: CHECK_GRIP job 25 on job 24's pick accepted")
    regs = wait_for_echo(client, 25)
    check(regs[JOB_ECHO] == 25 and regs[STATUS] & DONE and not regs[STATUS] & PICK_VALID,
          f"{order}: check job 25: done, no pick: status {regs[STATUS]:#06x}")
    check(regs[GRIP_STATE:GRIP_OF_JOB + 1] == [POSE_ERROR, 24], f"{order}: GRIP_STATE 2 (pose error) of job 24")
    floats = grip_floats(regs, order)
    check(floats == grip_pose_for_job(24) + sim_grip_errors(POSE_ERROR), f"{order}: tool_T_part and errors {floats}")
    rr = client.write_registers(0, [NEXT], slave=1)
    check(rr.isError() and rr.exception_code == 3, f"{order}: NEXT on a check's result -> exception 3")
    rr = client.write_registers(0, [CHECK_GRIP, 26, 3, 0], slave=1)
    check(rr.isError() and rr.exception_code == 3, f"{order}: CHECK_GRIP without a pick -> exception 3")

    # The pick result and the check in one write: PICK_RESULT ok for job 26, then CHECK_GRIP 27.
    check(not client.write_registers(0, [1, 26, 3, 0], slave=1).isError(), f"{order}: trigger job 26 accepted")
    wait_for_echo(client, 26)
    wr = client.write_registers(0, [CHECK_GRIP, 27, 3, 0, 1, 26], slave=1)
    check(not wr.isError(), f"{order}: PICK_RESULT and CHECK_GRIP job 27 in one write accepted")
    regs = wait_for_echo(client, 27)
    check(regs[GRIP_STATE:GRIP_OF_JOB + 1] == [EXPECTED, 26], f"{order}: GRIP_STATE 1 (expected) of job 26")
    floats = grip_floats(regs, order)
    check(floats == grip_pose_for_job(26) + sim_grip_errors(EXPECTED), f"{order}: tool_T_part and errors {floats}")

    check(not client.write_registers(0, [1, 28, 3, 0], slave=1).isError(), f"{order}: trigger job 28 accepted")
    regs = wait_for_echo(client, 28)
    check(regs[GRIP_STATE:BLOCK] == [0] * (BLOCK - GRIP_STATE), f"{order}: a TRIGGER's result: 68..95 read 0")
    wr = client.write_registers(0, [CHECK_GRIP, 29, SIM_GRIP_RECIPE + 3, 0], slave=1)
    check(not wr.isError(), f"{order}: CHECK_GRIP job 29 accepted")
    regs = wait_for_echo(client, 29)
    check(regs[GRIP_STATE:GRIP_OF_JOB + 1] == [NOT_GRASPED, 28] and regs[GRIP_X:GRIP_X + 16] == [0] * 16,
          f"{order}: GRIP_STATE 3 (not grasped) of job 28, pose and errors 0.0")


def run_mbpoll(binary):
    mbpoll = shutil.which("mbpoll")
    if not mbpoll:
        print("mbpoll is not installed (tools/deps/motion.txt lists it)")
        sys.exit(77)
    for order in ("ABCD", "CDAB"):
        server = Server(binary, order)
        # mbpoll's -B means big-endian word order (ABCD); without it, CDAB.
        args = [mbpoll, "-m", "tcp", "-p", str(server.port), "-a", "1", "-0", "-1", "-r", str(TEST_VECTOR),
                "-c", "1", "-t", "4:float"] + (["-B"] if order == "ABCD" else []) + ["127.0.0.1"]
        out = subprocess.run(args, capture_output=True, text=True, timeout=20)
        lines = [l for l in out.stdout.splitlines() if l.startswith(f"[{TEST_VECTOR}]")]
        check(out.returncode == 0 and lines and lines[0].split(":")[1].strip() == "123456",
              f"{order}: mbpoll reads the test vector as 123456: {lines}")
        out = subprocess.run([mbpoll, "-m", "tcp", "-p", str(server.port), "-a", "1", "-0", "-1", "-r",
                              str(BLOCK - 1), "-c", "2", "127.0.0.1"], capture_output=True, text=True, timeout=20)
        text = out.stdout + out.stderr
        check("Illegal data address" in text, f"{order}: mbpoll read past the map -> illegal data address")
        if order == "ABCD":
            mbpoll_map_v3(mbpoll, server.port)
            mbpoll_map_v4(mbpoll, server.port)
            mbpoll_map_v5(mbpoll, server.port)
        server.close()


def mbpoll_map_v3(mbpoll, port):
    """TRIGGER, NEXT and PICK_RESULT written by mbpoll (map version 3)."""
    base = [mbpoll, "-m", "tcp", "-p", str(port), "-a", "1", "-0", "-1"]

    def write(address, *values):
        out = subprocess.run(base + ["-r", str(address), "127.0.0.1"] + [str(v) for v in values],
                             capture_output=True, text=True, timeout=20)
        return out.returncode, out.stdout + out.stderr

    def read(address, count):
        out = subprocess.run(base + ["-r", str(address), "-c", str(count), "127.0.0.1"],
                             capture_output=True, text=True, timeout=20)
        values = {}
        for line in out.stdout.splitlines():
            if line.startswith("["):
                key, value = line.split(":", 1)
                values[int(key.strip("[]"))] = int(value.split()[0])
        return values

    code, text = write(0, 1, 31, 3, 0)
    check(code == 0, f"mbpoll: TRIGGER job 31 written ({text.strip()[-60:]})")
    for _ in range(100):
        if read(JOB_ECHO, 1).get(JOB_ECHO) == 31:
            break
        time.sleep(0.02)
    regs = read(PICK_RANK, 3)
    check(regs.get(PICK_RANK) == 0 and regs.get(PICKS_LEFT) == 2, f"mbpoll: job 31 first choice, 2 more: {regs}")
    code, _ = write(0, NEXT)
    regs = read(PICK_RANK, 2)
    check(code == 0 and regs.get(PICK_RANK) == 1 and regs.get(PICKS_LEFT) == 1, f"mbpoll: NEXT -> rank 1: {regs}")
    code, _ = write(4, 2, 31)
    check(code == 0, "mbpoll: PICK_RESULT missed for job 31")
    check(read(4, 2) == {4: 2, 5: 31}, "mbpoll: PICK_RESULT reads back")
    write(0, NEXT)
    code, text = write(0, NEXT)
    check(code != 0 and "Illegal data value" in text, "mbpoll: NEXT with no pick left -> illegal data value")


def mbpoll_calls(mbpoll, port):
    """(run, wait_for_echo) for one mbpoll session on `port` (unit 1, 0-based, one poll each):
    run(*args) -> (exit code, output, {register: value text}); wait_for_echo(job) -> whether
    JOB_ID_ECHO reached `job` within 2 s."""
    base = [mbpoll, "-m", "tcp", "-p", str(port), "-a", "1", "-0", "-1"]

    def run(*args):
        out = subprocess.run(base + [str(a) for a in args], capture_output=True, text=True, timeout=20)
        values = {}
        for line in out.stdout.splitlines():
            if line.startswith("["):
                key, value = line.split(":", 1)
                values[int(key.strip("[]"))] = value.strip()
        return out.returncode, out.stdout + out.stderr, values

    def wait_for_echo(job):
        for _ in range(100):
            if run("-r", JOB_ECHO, "-c", 1, "127.0.0.1")[2].get(JOB_ECHO) == str(job):
                return True
            time.sleep(0.02)
        return False

    return run, wait_for_echo


def mbpoll_map_v4(mbpoll, port):
    """A result asking for a second look read, and LOOK written, by mbpoll (map version 4, ABCD)."""
    run, wait_for_echo = mbpoll_calls(mbpoll, port)

    code, _, _ = run("-r", 0, "127.0.0.1", 1, 41, SIM_LOOK_RECIPE + 1, 0)
    check(code == 0 and wait_for_echo(41), "mbpoll: TRIGGER job 41 (second look wanted) done")
    _, _, regs = run("-r", STATUS, "-c", 1, "127.0.0.1")
    check(int(regs.get(STATUS, "0")) & LOOK_WANTED, f"mbpoll: job 41 LOOK_WANTED: {regs}")
    _, _, regs = run("-r", LOOK_REASON, "-c", 1, "127.0.0.1")
    check(regs.get(LOOK_REASON) == "1", f"mbpoll: LOOK_REASON 1: {regs}")
    _, _, regs = run("-r", LOOK_X, "-c", 6, "-t", "4:float", "-B", "127.0.0.1")
    pose = [float(regs.get(LOOK_X + 2 * i, "nan")) for i in range(6)]
    check(pose == look_pose_for_job(41), f"mbpoll: look pose {pose}")
    code, _, _ = run("-r", 0, "127.0.0.1", LOOK, 42, SIM_LOOK_RECIPE + 1, 0)
    check(code == 0 and wait_for_echo(42), "mbpoll: LOOK job 42 done")
    code, text, _ = run("-r", 0, "127.0.0.1", LOOK, 43, SIM_LOOK_RECIPE + 1, 0)
    check(code != 0 and "Illegal data value" in text, "mbpoll: LOOK without LOOK_WANTED -> illegal data value")


def mbpoll_map_v5(mbpoll, port):
    """CHECK_GRIP written, and its result read, by mbpoll (map version 5, ABCD)."""
    run, wait_for_echo = mbpoll_calls(mbpoll, port)

    # Job 42 (mbpoll_map_v4's LOOK) left a pick in the registers: check it.
    code, _, _ = run("-r", 0, "127.0.0.1", CHECK_GRIP, 44, SIM_GRIP_RECIPE + 2, 0)
    check(code == 0 and wait_for_echo(44), "mbpoll: CHECK_GRIP job 44 done")
    _, _, regs = run("-r", GRIP_STATE, "-c", 2, "127.0.0.1")
    check(regs.get(GRIP_STATE) == str(POSE_ERROR) and regs.get(GRIP_OF_JOB) == "42",
          f"mbpoll: GRIP_STATE 2 of job 42: {regs}")
    _, _, regs = run("-r", GRIP_X, "-c", 8, "-t", "4:float", "-B", "127.0.0.1")
    floats = [float(regs.get(GRIP_X + 2 * i, "nan")) for i in range(8)]
    check(floats == grip_pose_for_job(42) + sim_grip_errors(POSE_ERROR), f"mbpoll: tool_T_part and errors {floats}")
    code, text, _ = run("-r", 0, "127.0.0.1", CHECK_GRIP, 45, SIM_GRIP_RECIPE + 2, 0)
    check(code != 0 and "Illegal data value" in text, "mbpoll: CHECK_GRIP on a check's result -> illegal data value")
    code, text, _ = run("-r", GRIP_STATE, "127.0.0.1", 1)
    check(code != 0 and "Illegal data address" in text, "mbpoll: write to GRIP_STATE -> illegal data address")


if __name__ == "__main__":
    binary, client = sys.argv[1], sys.argv[2]
    {"pymodbus": run_pymodbus, "mbpoll": run_mbpoll}[client](binary)
    print(f"{len(failures)} failed" if failures else "all checks passed")
    sys.exit(1 if failures else 0)
