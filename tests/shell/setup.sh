#!/usr/bin/env bash
# scripts/setup's routes without touching the machine: each case runs it with stub commands
# first on PATH (no pkg-config HDF5, no dpkg packages, not root, no sudo, an apt-get that
# records its calls) and a fake HDF5 prefix where a case wants one. Run by scripts/test;
# alone: tests/shell/setup.sh (prints each case's output with -v).
set -euo pipefail
cd "$(dirname "$0")/../.."
verbose=0
[ "${1:-}" = -v ] && verbose=1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
stubs="$tmp/bin"
mkdir -p "$stubs"
stub() { printf '#!/bin/sh\n%s\n' "$2" >"$stubs/$1"; chmod +x "$stubs/$1"; }
stub pkg-config 'exit 1'
stub dpkg-query 'exit 1'
stub h5cc 'exit 1'
stub sudo 'exit 1'
stub apt-get 'echo "apt-get $*" >>"$APT_LOG"; exit 0'
stub id 'if [ "$1" = -u ]; then echo "${FAKE_UID:-1000}"; else /usr/bin/id "$@"; fi'
fake="$tmp/hdf5"
mkdir -p "$fake/include" "$fake/lib"
touch "$fake/include/hdf5.h" "$fake/include/hdf5_hl.h" "$fake/lib/libhdf5.so" "$fake/lib/libhdf5_hl.so"

failures=0
setup_args="" # scripts/setup's flags in the next cases
# run <name> <expected exit> <expected text...> -- <env assignments...>
run() {
  local name=$1 want=$2; shift 2
  local texts=()
  while [ "$1" != -- ]; do texts+=("$1"); shift; done
  shift
  : >"$tmp/apt.log"
  local rc=0
  env -u HDF5_DIR -u HDF5_ROOT -u CONDA_PREFIX -u LD_LIBRARY_PATH APT_LOG="$tmp/apt.log" \
    PATH="$stubs:$PATH" "$@" scripts/setup $setup_args >"$tmp/out" 2>&1 || rc=$?
  local ok=1
  [ "$rc" = "$want" ] || ok=0
  for t in "${texts[@]}"; do grep -qF -- "$t" "$tmp/out" "$tmp/apt.log" || { ok=0; echo "  missing: $t"; }; done
  if [ "$ok" = 1 ]; then echo "ok   $name"; else echo "FAIL $name (exit $rc, wanted $want)"; failures=$((failures + 1)); fi
  if [ "$verbose" = 1 ] || [ "$ok" = 0 ]; then sed 's/^/    | /' "$tmp/out" "$tmp/apt.log"; fi
}
no_apt_call() { [ ! -s "$tmp/apt.log" ] || { echo "FAIL $1: apt-get was called"; failures=$((failures + 1)); }; }

run "no HDF5, no root: says what to do, never calls apt" 1 \
  "module load hdf5" "conda install -c conda-forge hdf5" "export HDF5_DIR=" "--enable-hl" "brew install hdf5" --
no_apt_call "no HDF5, no root"
run "HDF5_DIR with the high-level library: used, no apt" 0 \
  "using HDF5 from HDF5_DIR=$fake" "LD_LIBRARY_PATH=\"$fake/lib" -- HDF5_DIR="$fake"
no_apt_call "HDF5_DIR"
run "HDF5_DIR without the high-level library: refused" 1 "lacks include/hdf5.h" -- HDF5_DIR="$tmp"
run "a conda environment: named for HDF5_DIR" 1 "export HDF5_DIR=$fake" -- CONDA_PREFIX="$fake"
run "an HPC module's HDF5_ROOT: named for HDF5_DIR" 1 "export HDF5_DIR=$fake" -- HDF5_ROOT="$fake"
no_apt_call "HDF5_ROOT"
stub rustc 'echo "rustc 1.63.0"'
run "Debian's rustc 1.63: rustup named" 1 "older than tsim's minimum" "rustup" -- HDF5_DIR="$fake"
rm "$stubs/rustc"
# rustup's minimal profile: no rustfmt; setup adds it (and clippy) with rustup, as the user.
real_cargo=$(command -v cargo)
stub cargo "[ \"\$1\" = fmt ] && exit 1; exec $real_cargo \"\$@\""
stub rustup 'echo "rustup $*" >>"$APT_LOG"'
run "rustfmt missing: rustup component add" 0 "rustup component add rustfmt clippy" -- HDF5_DIR="$fake"
rm "$stubs/cargo" "$stubs/rustup"
run "root without HDF5: apt installs libhdf5-dev" 0 "apt-get install -y -qq libhdf5-dev pkg-config" -- FAKE_UID=0
setup_args=--slurm
run "--slurm as root: apt installs Slurm's daemons and client" 0 "slurmctld slurmd slurm-client" -- FAKE_UID=0
run "--slurm, no root: named as optional, never installed" 0 "Slurm with --slurm" -- HDF5_DIR="$fake"
no_apt_call "--slurm, no root"
setup_args=""

# No C compiler: PATH holds the stubs and links to every system tool but the C compilers.
nocc="$tmp/nocc"
mkdir -p "$nocc"
for f in /usr/bin/*; do
  case "${f##*/}" in cc | gcc | gcc-* | c89* | c99* | *-linux-gnu-gcc*) ;; *) ln -s "$f" "$nocc/" ;; esac
done
run "no C compiler, no root: names build-essential" 1 "build-essential" "module load gcc" -- \
  HDF5_DIR="$fake" PATH="$stubs:$nocc"

# --user-hdf5: apt-get download (stubbed: copies two fake .debs built here) and dpkg-deb -x
# into .local/hdf5 of a copy of the checkout, never as root, never apt-get install.
pkgroot="$tmp/pkg"
mkdir -p "$pkgroot/dev/DEBIAN" "$pkgroot/dev/usr/include/hdf5/serial" "$pkgroot/dev/usr/lib/x86_64-linux-gnu/hdf5/serial" \
  "$pkgroot/rt/DEBIAN" "$pkgroot/rt/usr/lib/x86_64-linux-gnu"
touch "$pkgroot/dev/usr/include/hdf5/serial/hdf5.h" "$pkgroot/dev/usr/include/hdf5/serial/hdf5_hl.h" \
  "$pkgroot/rt/usr/lib/x86_64-linux-gnu/libhdf5_serial_hl.so.100"
ln -s ../../../../include/hdf5/serial "$pkgroot/dev/usr/lib/x86_64-linux-gnu/hdf5/serial/include"
ln -s . "$pkgroot/dev/usr/lib/x86_64-linux-gnu/hdf5/serial/lib"
ln -s ../../libhdf5_serial_hl.so.100 "$pkgroot/dev/usr/lib/x86_64-linux-gnu/hdf5/serial/libhdf5_hl.so"
printf 'Package: libhdf5-dev\nVersion: 1\nArchitecture: all\nMaintainer: t <t@t>\nDescription: t\n' >"$pkgroot/dev/DEBIAN/control"
printf 'Package: libhdf5-hl-100\nVersion: 1\nArchitecture: all\nMaintainer: t <t@t>\nDescription: t\n' >"$pkgroot/rt/DEBIAN/control"
dpkg-deb -b "$pkgroot/dev" "$tmp/libhdf5-dev.deb" >/dev/null
dpkg-deb -b "$pkgroot/rt" "$tmp/libhdf5-hl-100.deb" >/dev/null
stub apt-cache 'echo "libhdf5-dev"; echo "  Depends: libhdf5-hl-100"; echo "  Depends: zlib1g-dev"'
stub apt-get "echo \"apt-get \$*\" >>\"\$APT_LOG\"; case \"\$1\" in -s) echo 'Inst libhdf5-hl-100 (1 Debian:12)';; download) cp $tmp/*.deb .;; esac"
checkout="$tmp/checkout"
mkdir -p "$checkout/scripts" && cp scripts/setup "$checkout/scripts/" && cp Cargo.toml "$checkout/"
pushd "$checkout" >/dev/null
setup_args=--user-hdf5
run "--user-hdf5: Debian's HDF5 unpacked without root" 0 \
  "unpacked Debian's HDF5 (2 packages, no root)" ". .local/hdf5/env" "apt-get download -q libhdf5-dev libhdf5-hl-100" \
  "using HDF5 from HDF5_DIR=$checkout/.local/hdf5/root/usr/lib/x86_64-linux-gnu/hdf5/serial" --
setup_args=""
popd >/dev/null
grep -q "apt-get install" "$tmp/apt.log" && { echo "FAIL --user-hdf5 called apt-get install"; failures=$((failures + 1)); }
grep -qF "export LD_LIBRARY_PATH=\"$checkout/.local/hdf5/root/usr/lib/x86_64-linux-gnu:" "$checkout/.local/hdf5/env" ||
  { echo "FAIL --user-hdf5: env file"; cat "$checkout/.local/hdf5/env"; failures=$((failures + 1)); }

[ "$failures" = 0 ] || { echo "$failures failure(s)"; exit 1; }
