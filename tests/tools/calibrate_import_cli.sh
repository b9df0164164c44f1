#!/bin/sh
# mfc-calibrate import as a user runs it, on the files OpenCV's samples and ROS write
# (tests/vision/calib/foreign): the camera file written, the defaults named, an existing file
# replaced only with --apply, every refusal with its reason and exit status, nothing written then.
set -eu
tool="$1/tools/calibrate/mfc-calibrate"
src="$2"
work="$3"
foreign="$src/tests/vision/calib/foreign"
rm -rf "$work"; mkdir -p "$work"; cd "$work"
fail() { echo "FAIL: $*"; exit 1; }
# run EXPECTED_STATUS LOG ARGS...: runs the tool, its stdout and stderr to LOG, checks the status.
run() {
  want=$1; log=$2; shift 2
  set +e
  "$tool" "$@" > "$log" 2>&1
  rc=$?
  set -e
  [ "$rc" -eq "$want" ] || fail "mfc-calibrate $* exited $rc, expected $want: $(cat "$log")"
}
has() { grep -qF -- "$2" "$1" || fail "$1 lacks '$2': $(cat "$1")"; }

# OpenCV's sample: a new camera file is written at once; every MFC key is a default, named.
run 0 sample.log import "$foreign/opencv_sample.yml" --out cam.yaml
has sample.log "as an OpenCV calibration sample file"
has sample.log "read: image_width, image_height, camera_matrix, distortion_coefficients"
has sample.log "defaults used: working_distance_mm 300 mm (--working-distance), flashes.ring_radius_mm 40 mm (--flash-ring-radius), flashes.first_angle_deg 0 deg (--flash-first-angle), flashes.step_deg 45 deg (--flash-step), flashes.plane_z_mm 0 mm (--flash-plane-z)"
has sample.log 'wrote "cam.yaml"'
# Both are FileStorage's text of the same doubles: the intrinsics went through unchanged.
grep -A5 '^camera_matrix' "$foreign/opencv_sample.yml" > k.want
grep -A5 '^camera_matrix' cam.yaml > k.got
cmp -s k.want k.got || fail "camera_matrix differs: $(cat k.got)"
has cam.yaml "working_distance_mm: 300."
has cam.yaml "ring_radius_mm: 40."

# ROS camera_info with every MFC key given: no default used.
run 0 ros.log import "$foreign/ros_plumb_bob.yaml" --out ros.yaml --working-distance 420 --flash-ring-radius 55 \
  --flash-first-angle 22.5 --flash-step -45 --flash-plane-z 3
has ros.log "as a ROS camera_info file"
has ros.log "distortion (plumb_bob): -0.228216632 0.3045496686 0.0007632785138 -0.0005321768843 0"
has ros.log "defaults used: none"
has ros.yaml "working_distance_mm: 420."
has ros.yaml "ring_radius_mm: 55."
has ros.yaml "first_angle_deg: 2.2500000000000000e+01"
has ros.yaml "step_deg: -45."
has ros.yaml "plane_z_mm: 3."
has ros.yaml "data: [ 1.4088460733653735e+03, 0., 6.4911805288526580e+02, 0.,"

# An existing camera file: shown, not replaced, without --apply; with it replaced (old kept),
# its MFC keys kept where no option is given; rollback restores it.
cp ros.yaml before.yaml
run 0 preview.log import "$foreign/ros_ost.yaml" --out ros.yaml
has preview.log "would write"
has preview.log "working_distance_mm: 420 mm (from ros.yaml)"
cmp -s ros.yaml before.yaml || fail "import without --apply changed ros.yaml"
run 0 apply.log import "$foreign/ros_ost.yaml" --out ros.yaml --flash-step 45 --apply
has apply.log "defaults used: none"
has apply.log 'previous kept as "ros.yaml.previous"'
cmp -s ros.yaml.previous before.yaml || fail "the replaced file was not kept"
has ros.yaml "data: [ 1.4088460700000001e+03, 0., 6.4911805000000004e+02, 0.,"
has ros.yaml "working_distance_mm: 420."
has ros.yaml "step_deg: 45."
run 0 rollback.log rollback --out ros.yaml
cmp -s ros.yaml before.yaml || fail "rollback did not restore the file"

# Refused files: exit 1, the file and key named with the reason, nothing written.
run 1 fisheye.log import "$foreign/opencv_tutorial_fisheye.yml" --out fisheye.yaml
has fisheye.log "opencv_tutorial_fisheye.yml:12: key 'fisheye_model': fisheye lenses are not supported (mfcd's camera model is the pinhole with polynomial distortion)"
has fisheye.log "nothing written"
run 1 equidistant.log import "$foreign/ros_equidistant.yaml" --out fisheye.yaml
has equidistant.log "ros_equidistant.yaml:8: key 'distortion_model': 'equidistant': fisheye lenses are not supported"
sed '/^camera_matrix:/,/^  data:/d' "$foreign/ros_plumb_bob.yaml" > no_k.yaml
run 1 no_k.log import no_k.yaml --out fisheye.yaml
has no_k.log "no_k.yaml:1: key 'camera_matrix': missing"
sed 's/^image_width: 1280/image_width: 0/' "$foreign/ros_plumb_bob.yaml" > no_size.yaml
run 1 no_size.log import no_size.yaml --out fisheye.yaml
has no_size.log "no_size.yaml:1: key 'image_width': must be in 1..20000 pixels, got 0"
[ ! -e fisheye.yaml ] || fail "a refused import wrote fisheye.yaml"
cp cam.yaml cam.before
run 1 base.log import "$foreign/opencv_sample.yml" --out cam.yaml --flash-plane-z 400 --apply
has base.log "key 'flashes': LED behind the working distance"
cmp -s cam.yaml cam.before || fail "a refused import changed cam.yaml"

# Usage errors: exit 2.
run 2 u1.log import --out x.yaml
has u1.log "import: give one calibration FILE (OpenCV or ROS YAML)"
run 2 u2.log import "$foreign/opencv_sample.yml" "$foreign/ros_ost.yaml" --out x.yaml
run 2 u3.log import "$foreign/opencv_sample.yml" --out x.yaml --working-distance -3
has u3.log "--working-distance -3: must be in (0, 100000] mm"
run 2 u4.log import "$foreign/opencv_sample.yml" --out x.yaml --flash-ring-radius wide
has u4.log "--flash-ring-radius 'wide': expected a number"
run 2 u5.log import "$foreign/opencv_sample.yml"
has u5.log "missing --out"
cp "$foreign/ros_ost.yaml" ost.yaml
run 2 u6.log import ost.yaml --out ost.yaml
has u6.log "is the file being imported"
run 2 u7.log rollback stray --out cam.yaml
has u7.log "unexpected argument 'stray'"
[ ! -e x.yaml ] || fail "a usage error wrote x.yaml"
echo "mfc-calibrate import CLI: ok"
