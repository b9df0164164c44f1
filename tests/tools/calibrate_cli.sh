#!/bin/sh
# mfc-calibrate as a user runs it: simulated captures saved to disk, calibrated from the
# files, applied with --apply only, rolled back; bad input leaves the camera file alone.
set -eu
tool="$1/tools/calibrate/mfc-calibrate"
src="$2"
work="$3"
rm -rf "$work"; mkdir -p "$work"; cd "$work"
cp "$src/config/camera-sim.yaml" cam.yaml
fail() { echo "FAIL: $*"; exit 1; }

# Intrinsics: render 20 views to disk, then calibrate from the directory.
"$tool" intrinsics --sim 20 --distortion none --out cam.yaml --save-views views > sim.log
cmp -s cam.yaml "$src/config/camera-sim.yaml" || fail "intrinsics without --apply changed cam.yaml"
grep -q "would write" sim.log || fail "no preview without --apply"
"$tool" intrinsics --images views --distortion none --out cam.yaml --apply > apply.log
grep -q "RMS reprojection" apply.log || fail "no RMS printed"
[ -f cam.yaml.previous ] || fail "previous calibration not kept"
cmp -s cam.yaml.previous "$src/config/camera-sim.yaml" || fail "previous is not the old file"
fx=$(grep -A4 camera_matrix cam.yaml | grep data | sed 's/.*\[ *\([^,]*\),.*/\1/')
awk -v fx="$fx" 'BEGIN { d = fx / 1100 - 1; if (d < 0) d = -d; exit !(d < 0.005) }' || fail "fx $fx not within 0.5 % of 1100"

# Hand-eye from a views list written by the simulator.
"$tool" hand-eye --mode eye-to-hand --camera "$src/config/camera-sim.yaml" --sim 12 --out cam.yaml \
  --save-views he > he-sim.log
[ -f he/views.yaml ] || fail "views.yaml not written"
"$tool" hand-eye --mode eye-to-hand --camera "$src/config/camera-sim.yaml" --views he/views.yaml \
  --out cam.yaml --apply > he.log
grep -q "mode: eye_to_hand" cam.yaml || fail "hand_eye section not written"

# Rollback restores the intrinsics-only file.
"$tool" rollback --out cam.yaml > rb.log
grep -q hand_eye cam.yaml && fail "rollback kept the hand-eye section"

# Bad input: images without a board -> error, nothing written.
cp cam.yaml before.yaml
mkdir blank
python3 -c "
import struct, zlib
def png(w, h, v):
    raw = b''.join(b'\x00' + bytes([v]) * w for _ in range(h))
    c = lambda t, d: struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d))
    return b'\x89PNG\r\n\x1a\n' + c(b'IHDR', struct.pack('>IIBBBBB', w, h, 8, 0, 0, 0, 0)) + c(b'IDAT', zlib.compress(raw)) + c(b'IEND', b'')
for i in range(8): open('blank/b%d.png' % i, 'wb').write(png(640, 480, 128))
"
if "$tool" intrinsics --images blank --out cam.yaml --apply > bad.log 2>&1; then fail "blank images calibrated"; fi
grep -q "not found" bad.log || fail "no 'not found' reason: $(cat bad.log)"
grep -q "too few views" bad.log || fail "no 'too few views' error: $(cat bad.log)"
cmp -s cam.yaml before.yaml || fail "failed calibration changed cam.yaml"
set +e
"$tool" hand-eye --mode sideways --camera cam.yaml --sim 3 --out cam.yaml > usage.log 2>&1
rc=$?
set -e
[ $rc -ne 0 ] || fail "bad mode accepted"
grep -q "sideways" usage.log || fail "bad mode not named"
cmp -s cam.yaml before.yaml || fail "usage error changed cam.yaml"
echo "mfc-calibrate CLI: ok"
