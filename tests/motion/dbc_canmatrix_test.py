#!/usr/bin/python3
"""docs/mfcd.dbc read by an independent DBC parser, python3-canmatrix (Debian), and checked
against the frames the code sends.

  dbc_canmatrix_test.py SOURCE_DIR DUMP_PROGRAM

DUMP_PROGRAM is tests/motion/can_frames_dump.cpp: every frame kind motion/can_frames builds,
for representative reports, as JSON lines with the values it encoded. Checks:

  * canmatrix loads the DBC without an error or warning and keeps every statement of it
    (its loader skips lines its patterns miss, so the statements are counted);
  * strict layout: no two signals of a frame share a bit (computed here from the start bit,
    length and byte order canmatrix reports, Intel and Motorola), every signal lies inside
    the frame, and every bit belongs to a signal (unused bits are named reserved signals);
    the bit model is checked against canmatrix's own decoder, and the overlap check against
    a built-in DBC with known overlaps;
  * BusType "CAN", a GenMsgSendType for every frame, GenMsgCycleTime for the periodic ones
    (the default heartbeat period in motion/can_publisher.hpp; status, heartbeat and version
    frames must be periodic), the VERSION "mfcd robot link N" with N = kCanDbcVersion of
    motion/can_frames.hpp (sent as DbcVersion), value tables for ErrorCode
    (every code of daemon/cycle.hpp CycleError) and the flags, a comment naming the unit of
    every signal;
  * every dumped frame: id and dlc equal the DBC frame's, each signal canmatrix decodes equals
    the value encoded within half the signal's factor and lies in the DBC [min|max], the
    decoded signals are exactly the frame's DBC signals, and every DBC frame is exercised.

Exit 0 when every check passes, 1 otherwise, also when python3-canmatrix is missing (a
declared dependency: tools/deps/motion.txt).
"""
import contextlib
import io
import itertools
import json
import logging
import math
import os
import re
import subprocess
import sys


class Collect(logging.Handler):
    """Keeps canmatrix's log records: a warning while loading the DBC is a failure."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.records = []

    def emit(self, record):
        self.records.append(record)


log = Collect()
logging.getLogger("canmatrix").addHandler(log)
logging.getLogger("canmatrix").propagate = False
try:
    import canmatrix.formats.dbc as dbc_format
except ImportError as e:
    print(f"FAIL python3-canmatrix cannot be imported ({e}); it is a declared dependency "
          "(tools/deps/motion.txt): apt-get install python3-canmatrix")
    sys.exit(1)
log.records.clear()  # formats canmatrix cannot load (ldf, ...) are not ours

failures = []


def check(cond, what, quiet=False):
    if not cond:
        print("FAIL " + what)
        failures.append(what)
    elif not quiet:
        print("ok   " + what)
    return cond


def load_dbc(data, what):
    """canmatrix's DBC loader on bytes; its own errors (log records, 'error with line' on
    stdout) are failures."""
    log.records.clear()
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        db = dbc_format.load(io.BytesIO(data))
    problems = [f"{r.levelname}: {r.getMessage()}" for r in log.records]
    if out.getvalue().strip():
        problems.append(out.getvalue().strip())
    check(not problems, f"{what}: canmatrix loads it without errors or warnings {problems}")
    return db


def signal_bits(sig):
    """Frame bits (LSB0: byte * 8 + bit in byte) a signal occupies, from the DBC start bit
    canmatrix reports. Intel: the start bit is the LSB and the signal runs up through the
    bits of the following bytes. Motorola: the start bit is the MSB; it runs down to bit 0 of
    its byte, then continues at bit 7 of the next byte."""
    pos = sig.get_startbit(bit_numbering=1)  # the DBC's own start bit for either byte order
    bits = []
    for _ in range(int(sig.size)):
        bits.append(pos)
        if sig.is_little_endian:
            pos += 1
        elif pos % 8 == 0:
            pos += 15
        else:
            pos -= 1
    return bits


def overlaps(frame):
    """Pairs of signals of the frame that share a bit, with the shared bits."""
    found = []
    for a, b in itertools.combinations(frame.signals, 2):
        shared = sorted(set(signal_bits(a)) & set(signal_bits(b)))
        if shared:
            found.append((a.name, b.name, shared))
    return found


def decoder_agrees(frame):
    """The bit model above against canmatrix's decoder: with only bit b set in the payload,
    exactly the signals that own bit b decode to a non-zero raw value."""
    nbits = int(frame.size) * 8
    for b in range(nbits):
        data = bytearray(int(frame.size))
        data[b // 8] = 1 << (b % 8)
        decoded = frame.unpack(bytes(data))
        got = {name for name, d in decoded.items() if d.raw_value != 0}
        want = {s.name for s in frame.signals if b in signal_bits(s)}
        if got != want:
            return f"bit {b}: decoder sets {sorted(got)}, bit model says {sorted(want)}"
    return None


# --- the overlap check itself, on layouts with known answers ---------------------------------
SELF_TEST_DBC = b'''VERSION ""
NS_ :
BS_:
BU_: A

BO_ 1 OldStatus: 8 A
 SG_ StatusWord : 0|16@1+ (1,0) [0|65535] "" A
 SG_ StatusReady : 0|1@1+ (1,0) [0|1] "" A
 SG_ JobId : 16|16@1+ (1,0) [0|65535] "" A

BO_ 2 MotorolaIntel: 8 A
 SG_ M16 : 7|16@0+ (1,0) [0|65535] "" A
 SG_ I8 : 16|8@1+ (1,0) [0|255] "" A
 SG_ M12 : 27|12@0+ (1,0) [0|4095] "" A
 SG_ I4 : 28|4@1+ (1,0) [0|15] "" A

BO_ 3 MotorolaOverlap: 8 A
 SG_ M16 : 7|16@0+ (1,0) [0|65535] "" A
 SG_ I1 : 0|1@1+ (1,0) [0|1] "" A
 SG_ M8 : 15|8@0+ (1,0) [0|255] "" A
'''


def self_test():
    db = load_dbc(SELF_TEST_DBC, "built-in overlap examples")
    frames = {f.name: f for f in db.frames}
    sigs = {f.name: {s.name: s for s in f.signals} for f in db.frames}
    # Motorola 7|16: bytes 0 and 1; 27|12: bits 27..24, then byte 4 (32..39).
    check(sorted(signal_bits(sigs["MotorolaIntel"]["M16"])) == list(range(16)),
          "self-test: Motorola 7|16 occupies bits 0..15")
    check(sorted(signal_bits(sigs["MotorolaIntel"]["M12"])) == list(range(24, 28)) + list(range(32, 40)),
          "self-test: Motorola 27|12 occupies bits 24..27 and 32..39")
    check([(a, b) for a, b, _ in overlaps(frames["OldStatus"])] == [("StatusWord", "StatusReady")],
          "self-test: the old StatusWord/StatusReady layout is reported as overlapping")
    # A naive start..start+length range would call M16/I8 and M12/I4 overlapping and miss
    # M16/I1: the byte order must be followed.
    check(overlaps(frames["MotorolaIntel"]) == [],
          "self-test: Motorola and Intel signals in adjacent bits do not overlap")
    check(sorted((a, b) for a, b, _ in overlaps(frames["MotorolaOverlap"])) == [("M16", "I1"), ("M16", "M8")],
          "self-test: Motorola 7|16 overlaps Intel 0|1 and Motorola 15|8")
    for f in db.frames:
        problem = decoder_agrees(f)
        check(problem is None, f"self-test: bit model agrees with canmatrix's decoder in {f.name} ({problem})")


# --- docs/mfcd.dbc -----------------------------------------------------------------------------
STATEMENTS = ("VERSION", "NS_", "BS_:", "BU_:", "BO_", "SG_", "CM_", "BA_DEF_", "BA_DEF_DEF_", "BA_", "VAL_")


def statement_counts(text):
    """Statements of the DBC by keyword, and lines that are none of the known ones."""
    counts, unknown, in_ns = {}, [], False
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            in_ns = False
            continue
        if in_ns and line[0] in " \t":  # the NS_ keyword list
            continue
        word = line.split()[0]
        if word not in STATEMENTS:
            unknown.append(f"line {n}: {line}")
            continue
        in_ns = word == "NS_"
        key = word
        if word in ("CM_", "BA_") and len(line.split()) > 2:
            second = line.split()[1] if word == "CM_" else line.split()[2]
            key = f"{word} {second}" if second in ("BU_", "BO_", "SG_") else f"{word} global"
        counts[key] = counts.get(key, 0) + 1
    return counts, unknown


def check_statements(text, db):
    counts, unknown = statement_counts(text)
    check(not unknown, f"every line is a known DBC statement {unknown}")
    signals = [s for f in db.frames for s in f.signals]
    kept = {
        "BO_": len(db.frames),
        "SG_": len(signals),
        "VAL_": sum(1 for s in signals if s.values),
        "CM_ SG_": sum(1 for s in signals if s.comment),
        "CM_ BO_": sum(1 for f in db.frames if f.comment),
        "CM_ BU_": sum(1 for e in db.ecus if e.comment),
        "BA_ BO_": sum(len(f.attributes) for f in db.frames),
        "BA_ global": len(db.attributes),
        "BA_DEF_": len(db.global_defines) + len(db.frame_defines) + len(db.signal_defines) + len(db.ecu_defines),
    }
    for key, n in kept.items():
        check(counts.get(key, 0) == n, f"canmatrix kept all {counts.get(key, 0)} {key} statements (it has {n})")


def check_layout(db):
    for f in db.frames:
        nbits = int(f.size) * 8
        owner = {}
        for s in f.signals:
            bits = signal_bits(s)
            check(all(0 <= b < nbits for b in bits), f"{f.name}.{s.name} lies inside the {f.size}-byte frame", quiet=True)
            for b in bits:
                owner.setdefault(b, []).append(s.name)
        found = overlaps(f)
        check(not found, f"{f.name}: no overlapping signals {found}")
        uncovered = [b for b in range(nbits) if b not in owner]
        check(not uncovered, f"{f.name}: every bit belongs to a signal (uncovered: {uncovered})")
        problem = decoder_agrees(f)
        check(problem is None, f"{f.name}: bit model agrees with canmatrix's decoder ({problem})")
        check(not f.arbitration_id.extended and f.arbitration_id.id <= 0x7FF and int(f.size) == 8,
              f"{f.name}: classic frame, 11-bit id, 8 bytes")


def cycle_errors(source_dir):
    """CycleError codes from daemon/cycle.hpp: the values ErrorCode carries."""
    text = open(os.path.join(source_dir, "daemon/cycle.hpp")).read()
    body = re.search(r"enum class CycleError[^{]*\{(.*?)\};", text, re.S)
    if not check(body is not None, "daemon/cycle.hpp declares enum class CycleError"):
        return {}
    return {int(v): name for name, v in re.findall(r"(\w+)\s*=\s*(\d+)\s*,", body.group(1))}


# The frames sent every heartbeat period (motion/can_publisher.cpp).
PERIODIC = ("MFCD_Status", "MFCD_Heartbeat", "MFCD_Version")


def check_version(source_dir, text):
    """The DBC's VERSION "mfcd robot link N" and kCanDbcVersion, the N mfcd sends as DbcVersion."""
    version = re.match(r'VERSION "mfcd robot link (\d+)"\s*$', text.splitlines()[0]) if text else None
    frames_hpp = open(os.path.join(source_dir, "motion/can_frames.hpp")).read()
    sent = re.search(r"kCanDbcVersion = (\d+);", frames_hpp)
    if check(version is not None and sent is not None,
             "docs/mfcd.dbc starts with VERSION \"mfcd robot link N\"; motion/can_frames.hpp has kCanDbcVersion"):
        check(int(version.group(1)) == int(sent.group(1)),
              f"DBC version {version.group(1)} is kCanDbcVersion {sent.group(1)}, the DbcVersion mfcd sends")


def check_attributes(source_dir, db):
    check(db.attributes.get("BusType") == "CAN", f"BusType is \"CAN\" (got {db.attributes.get('BusType')!r})")
    send_types = getattr(db.frame_defines.get("GenMsgSendType"), "values", [])
    check(bool(send_types), "GenMsgSendType is defined as a frame ENUM attribute")
    publisher = open(os.path.join(source_dir, "motion/can_publisher.hpp")).read()
    period = re.search(r"heartbeat_period\{(\d+)\}", publisher)
    check(period is not None, "motion/can_publisher.hpp has the default heartbeat_period")
    period_ms = int(period.group(1)) if period else None
    for f in db.frames:
        send = f.attributes.get("GenMsgSendType")
        check(send in send_types and send != "NoMsgSendType", f"{f.name}: GenMsgSendType {send!r}")
        cycle = int(f.attributes.get("GenMsgCycleTime", 0))
        if send is not None and send.startswith("Cyclic"):
            check(cycle == period_ms, f"{f.name}: GenMsgCycleTime {cycle} ms is the default heartbeat period {period_ms} ms")
        else:
            check(cycle == 0, f"{f.name}: event frame without GenMsgCycleTime (got {cycle})")
    frames = {f.name: f for f in db.frames}
    for name in PERIODIC:
        check(frames.get(name) is not None and
              frames[name].attributes.get("GenMsgSendType", "").startswith("Cyclic"),
              f"{name} is periodic")

    codes = cycle_errors(source_dir)
    error_code = frames["MFCD_Status"].signal_by_name("ErrorCode") if "MFCD_Status" in frames else None
    table = {int(k): v for k, v in error_code.values.items()} if error_code else {}
    check(bool(codes) and sorted(table) == sorted(codes),
          f"ErrorCode value table has exactly the CycleError codes {sorted(codes)} (got {sorted(table)})")
    check(all(table.get(k) for k in codes), "every ErrorCode value has a description")
    no_unit = []
    for f in db.frames:
        for s in f.signals:
            if int(s.size) == 1:
                check(sorted(int(k) for k in s.values) == [0, 1], f"{f.name}.{s.name}: value table for 0 and 1")
            comment = s.comment or ""
            if "Unit:" not in comment or (s.unit and s.unit not in comment.split("Unit:", 1)[1]):
                no_unit.append(f"{f.name}.{s.name}")
    check(not no_unit, f"every signal's comment names its unit (\"Unit: ...\", the SG_ unit if it has one) {no_unit}")


def check_frames(db, dump_program):
    run = subprocess.run([dump_program], capture_output=True, text=True, timeout=60)
    check(run.returncode == 0, f"{os.path.basename(dump_program)} exits 0 ({run.stderr.strip()})")
    lines = [json.loads(line) for line in run.stdout.splitlines() if line.strip()]
    check(len(lines) > 0, f"{len(lines)} frames dumped")
    frames = {f.name: f for f in db.frames}
    seen = {}
    compared = 0
    for rec in lines:
        where = f"case {rec['case']} {rec['frame']}"
        f = frames.get(rec["frame"])
        if not check(f is not None, f"{where}: frame is in the DBC", quiet=True):
            continue
        seen[f.name] = seen.get(f.name, 0) + 1
        data = bytes.fromhex(rec["data"])
        check(rec["id"] == f.arbitration_id.id, f"{where}: id 0x{rec['id']:x} is the DBC's 0x{f.arbitration_id.id:x}", quiet=True)
        check(rec["dlc"] == int(f.size) == len(data), f"{where}: dlc {rec['dlc']} ({len(data)} bytes) is the DBC's {f.size}", quiet=True)
        if len(data) != int(f.size):
            continue
        decoded = f.decode(data)
        check(set(decoded) == set(rec["signals"]),
              f"{where}: encoded signals {sorted(rec['signals'])} are the DBC's {sorted(decoded)}", quiet=True)
        for name, want in rec["signals"].items():
            if name not in decoded:
                continue
            sig = decoded[name].signal
            got = float(decoded[name].phys_value)
            # Half a step of the factor (the encoder rounds to nearest), plus double rounding
            # of value / factor in the encoder, far below a step.
            tolerance = float(sig.factor) / 2 + 1e-9 + 1e-12 * abs(want)
            check(math.isfinite(got) and abs(got - want) <= tolerance,
                  f"{where}: {name} decodes to {got}, encoded {want} (tolerance {tolerance:g})", quiet=True)
            check(float(sig.min) <= got <= float(sig.max),
                  f"{where}: {name} = {got} within the DBC range [{sig.min}|{sig.max}]", quiet=True)
            compared += 1
    check(set(seen) == set(frames), f"every DBC frame is exercised: {seen} of {sorted(frames)}")
    check(compared > 0, f"{compared} signal values decoded by canmatrix equal the encoded ones")


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    source_dir, dump_program = sys.argv[1], sys.argv[2]
    self_test()
    path = os.path.join(source_dir, "docs/mfcd.dbc")
    raw = open(path, "rb").read()
    db = load_dbc(raw, "docs/mfcd.dbc")
    check(len(db.frames) == 6, f"docs/mfcd.dbc has the 6 frames mfcd sends (got {len(db.frames)})")
    check_statements(raw.decode("iso-8859-1"), db)
    check_version(source_dir, raw.decode("iso-8859-1"))
    check_layout(db)
    check_attributes(source_dir, db)
    check_frames(db, dump_program)
    print(f"{len(failures)} failure(s)" if failures else "all checks passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
