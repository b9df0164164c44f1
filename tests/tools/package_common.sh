# Shared by package_install_tree.sh and package_deb.sh (sourced, not run): what an installed mfcd
# tree or .deb must hold, checked on a listing of its files (one path per line, relative to the
# root, no leading "./" or "/"). packaging/CMakeLists.txt is what puts the files there.

fail() { echo "FAIL: $*"; exit 1; }

# One path of LISTING must match the anchored extended regex RE; the systemd and udev directories
# may be /lib/... (Debian 12's pkg-config values) or /usr/lib/... (upstream's).
expect_path() {
  n=$(grep -c -E "^$2\$" "$1" || true)
  [ "$n" -eq 1 ] || fail "expected one file matching '$2', found $n"
}

# check_listing LISTING SRC PROGRAM...: every program in usr/bin and nothing else there (no test or
# benchmark binaries), the unit, the sysusers/tmpfiles/udev files, the configuration, the
# inactive drop-ins and every page of docs/ with the DBC file.
check_listing() {
  listing="$1" src="$2"; shift 2
  for p in "$@"; do expect_path "$listing" "usr/bin/$p"; done
  extra=$(grep -E '^usr/bin/' "$listing" | sed 's|^usr/bin/||' | while read -r b; do
            case " $* " in *" $b "*) ;; *) echo "$b" ;; esac
          done)
  [ -z "$extra" ] || fail "usr/bin holds programs that are not to ship: $extra"
  expect_path "$listing" '(usr/)?lib/systemd/system/mfcd\.service'
  expect_path "$listing" '(usr/)?lib/sysusers\.d/mfcd\.conf'
  expect_path "$listing" '(usr/)?lib/tmpfiles\.d/mfcd\.conf'
  expect_path "$listing" '(usr/)?lib/udev/rules\.d/60-mfcd-gpio\.rules'
  expect_path "$listing" 'etc/mfcd/mfcd\.yaml'
  expect_path "$listing" 'usr/share/mfcd/camera-sim\.yaml'
  expect_path "$listing" 'usr/share/mfcd/cell\.yaml'
  expect_path "$listing" 'usr/share/mfcd/parts\.csv'
  expect_path "$listing" 'usr/share/mfcd/mfcd\.service\.d/can\.conf'
  expect_path "$listing" 'usr/share/mfcd/mfcd\.service\.d/plc-network\.conf\.example'
  for page in "$src"/docs/*.md "$src/docs/mfcd.dbc"; do
    expect_path "$listing" "usr/share/doc/mfcd/$(basename "$page" | sed 's/\./\\./g')"
  done
  # Nothing from the build or source tree under another name (e.g. a stray absolute destination).
  stray=$(grep -v -E '^(usr/bin|(usr/)?lib/(systemd/system|sysusers\.d|tmpfiles\.d|udev/rules\.d)|etc/mfcd|usr/share/(mfcd|doc/mfcd))/' "$listing" || true)
  [ -z "$stray" ] || fail "files outside the expected directories: $stray"
}
