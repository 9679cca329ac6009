#!/usr/bin/env bash
# sirad: checks `cmake --install` of a build tree (the Deploy.InstallRuns test).
#   deploy/check-install.sh BUILD_DIR
# Installs into a temporary prefix and checks what a farm machine gets: the programs (each
# answers --version with the git commit and OpenCL; sirad renders the Cornell box from there),
# the key script, the man pages, the profiles, and the systemd units naming the installed
# programs and passing `systemd-analyze verify`. Then a staged install (DESTDIR, prefix /usr),
# as a package build makes it: files under DESTDIR, units naming /usr/bin.
set -euo pipefail
build=$(realpath "$1")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "check-install: $*" >&2; exit 1; }

prefix=$tmp/prefix
cmake --install "$build" --prefix "$prefix" >/dev/null
for p in sirad sirad-node sirad-coordinator sirad-make-keys; do
  [[ -x $prefix/bin/$p ]] || fail "$prefix/bin/$p is not installed"
done
for p in sirad sirad-node sirad-coordinator; do
  v=$("$prefix/bin/$p" --version) || fail "$p --version failed"
  grep -Eq "^$p [0-9]+\.[0-9]+\.[0-9]+ \(git [0-9a-f]{12}(-dirty)?\)$" <<<"$(head -1 <<<"$v")" \
    || fail "$p --version: first line '$(head -1 <<<"$v")' is not 'NAME VERSION (git COMMIT)'"
  grep -q "^OpenCL" <<<"$v" || fail "$p --version names no OpenCL platform: $v"
  [[ -s $prefix/share/man/man1/$p.1 ]] || fail "no man page $prefix/share/man/man1/$p.1"
  man -l "$prefix/share/man/man1/$p.1" 2>/dev/null | grep -q -- "--version" || fail "$p.1 does not read as a man page"
done
man -l "$prefix/share/man/man1/sirad.1" 2>/dev/null | grep -q -- "--exchange-every" \
  || fail "sirad.1 lacks the subcommands' options"
for f in lan-1g.yaml hetero-16.yaml; do [[ -s $prefix/share/sirad/profiles/$f ]] || fail "profile $f not installed"; done
[[ -s $prefix/share/doc/sirad/FARM.md ]] || fail "FARM.md not installed"

# The installed program runs from there, with nothing of the build tree.
(cd "$tmp" && "$prefix/bin/sirad" render cornell --patches 200 --bundles 20 --width 16 --height 16 --out "$tmp/c" -q) \
  || fail "the installed sirad render failed"
[[ -s $tmp/c.exr && -s $tmp/c.png ]] || fail "the installed sirad render wrote no image"

units=$prefix/lib/systemd/system
for u in sirad-node.service sirad-coordinator@.service sirad-farm.service; do
  [[ -s $units/$u ]] || fail "unit $u not installed"
  grep -q "^ExecStart=$prefix/bin/sirad-" "$units/$u" || fail "$u does not name the installed program: $(grep ExecStart "$units/$u")"
done
if command -v systemd-analyze >/dev/null; then
  # A template is verified as an instance of it; the units' man pages are the installed ones.
  cp "$units/sirad-coordinator@.service" "$tmp/sirad-coordinator@cornell.service"
  MANPATH=$prefix/share/man systemd-analyze verify "$units/sirad-node.service" "$tmp/sirad-coordinator@cornell.service" \
    "$units/sirad-farm.service" \
    || fail "systemd-analyze verify refused the units"
else
  echo "check-install: systemd-analyze not installed: the units were not verified" >&2
fi

stage=$tmp/stage
DESTDIR=$stage cmake --install "$build" --prefix /usr >/dev/null
[[ -x $stage/usr/bin/sirad-node ]] || fail "DESTDIR install: no $stage/usr/bin/sirad-node"
grep -q "^ExecStart=/usr/bin/sirad-node " "$stage/usr/lib/systemd/system/sirad-node.service" \
  || fail "DESTDIR install: the unit does not name /usr/bin/sirad-node"
echo "check-install: ok ($prefix and DESTDIR=$stage with prefix /usr)"
