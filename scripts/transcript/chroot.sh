# The chroots of the transcripts (sourced by clean_debian and wheel): a fresh Debian 12
# `minbase` (+ ca-certificates, curl, git) made once by debootstrap into $base, a copy of it
# per route with /proc, /dev, /sys and the repository (read-only, at /src/tsim) mounted, and
# `step`, which records a command, its output, exit status and wall time into $out.
# Needs root and debootstrap on a Debian host; the caller sets `repo` and `out`.
base=/srv/tsim-fresh
[ "$(id -u)" = 0 ] || { echo "${0##*/}: needs root (debootstrap, chroot)" >&2; exit 2; }
command -v debootstrap >/dev/null || apt-get install -y -qq debootstrap
if [ ! -x "$base/usr/bin/curl" ]; then
  debootstrap --variant=minbase --include=ca-certificates,curl,git bookworm "$base" http://deb.debian.org/debian >/dev/null
fi

root_of() { echo "/srv/tsim-$1"; }
fresh() { # <route>: a copy of the fresh chroot with /proc, /dev and the repository (read-only)
  local r; r=$(root_of "$1")
  teardown "$1"; rm -rf "$r"; cp -a "$base" "$r"
  cp /etc/resolv.conf "$r/etc/resolv.conf"
  # debootstrap writes no /etc/hosts; Debian's installer and cloud images do.
  printf '127.0.0.1\tlocalhost\n::1\t\tlocalhost ip6-localhost ip6-loopback\n' >"$r/etc/hosts"
  # The host's own CAs (a network that inspects TLS has one), for curl, cargo and pip.
  cp /usr/local/share/ca-certificates/*.crt "$r/usr/local/share/ca-certificates/" 2>/dev/null || true
  chroot "$r" update-ca-certificates >/dev/null 2>&1
  printf 'PIP_CERT=/etc/ssl/certs/ca-certificates.crt\n' >>"$r/etc/environment"
  enter "$1"
}
enter() { # <route>: /proc, /dev and the repository (read-only) mounted in its chroot
  local r; r=$(root_of "$1")
  # /sys: slurmd's hwloc reads the CPU topology there. The host must not run its own test
  # cluster meanwhile: the chroot shares its network, and so its Slurm ports.
  mount -t proc proc "$r/proc"; mount --rbind /dev "$r/dev"; mount --rbind /sys "$r/sys"
  mkdir -p "$r/src/tsim"; mount --bind "$repo" "$r/src/tsim"; mount -o remount,bind,ro "$r/src/tsim"
}
teardown() {
  local r; r=$(root_of "$1")
  # Daemons the route started in its chroot (the test command's Slurm cluster) share the
  # host's ports: stop them.
  for p in /proc/[0-9]*; do
    [ "$(readlink "$p/root" 2>/dev/null)" = "$r" ] && { kill "${p#/proc/}" 2>/dev/null || true; }
  done
  for m in src/tsim sys dev proc; do mountpoint -q "$r/$m" 2>/dev/null && umount -R -l "$r/$m"; done; true
}
# `$ command` then its output, cargo's per-crate lines folded into one count; the exit
# status and wall time after it.
step() { # <route> <user> <command>
  local r; r=$(root_of "$1"); local prompt='#'; [ "$2" = root ] || prompt='$'
  printf '%s %s\n' "$prompt" "$3" >>"$out"
  local start=$SECONDS status=0
  chroot "$r" su - "$2" -c "set -o pipefail; cd ~ && $3" >"$r/tmp/step.log" 2>&1 || status=$?
  awk '/^ *(Compiling|Downloaded|Downloading|Fresh|Checking|Building|Locking|Adding|Updating|Blocking) / {n++; next}
       {print} END {if (n) print "  [" n " lines of cargo progress (Compiling, Downloaded, ...) left out]"}' \
    "$r/tmp/step.log" | { grep -v -E '^\s*$' || true; } | cut -c1-160 >>"$out"
  printf '[exit %s, %s s]\n\n' "$status" "$((SECONDS - start))" >>"$out"
  return 0
}
block() { printf '%s\n\n```console\n' "$1" >>"$out"; }
endblock() { printf '```\n\n' >>"$out"; }

ctx() { echo "Recorded $(date -u '+%Y-%m-%d %H:%M') UTC at commit $(git -C "$repo" rev-parse --short HEAD)."; echo; }
