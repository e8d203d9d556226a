#!/usr/bin/env bash
# The .deb as a plant upgrades it: cpack packs the build tree (with the /usr layout);
# dpkg-deb shows /etc/virtualbutcher/{virtualbutcherd.yaml,rig.yaml} as conffiles and the unit's
# Documentation= files inside; the rig shipped is a real-camera one (no vbrig:// URIs). Then in a
# scratch root (dpkg --root, its own database): install, edit rig.yaml as a site would,
# upgrade to a newer version of the package, and the edit is still there.
# Usage: package_test.sh <source dir> <build dir>
set -euo pipefail
src=$(realpath "$1")
build=$(realpath "$2")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

(cd "$work" && cpack -G DEB --config "$build/CPackConfig.cmake" -B "$work/pack" >"$work/cpack.log" 2>&1) ||
  { cat "$work/cpack.log"; fail "cpack"; }
deb=$(ls "$work"/pack/virtualbutcher_*.deb | head -1)
[ -s "$deb" ] || fail "no .deb"

conffiles=$(dpkg-deb --ctrl-tarfile "$deb" | tar -xO ./conffiles)
[ "$conffiles" = $'/etc/virtualbutcher/virtualbutcherd.yaml\n/etc/virtualbutcher/rig.yaml' ] ||
  fail "conffiles are: $conffiles"
contents=$(dpkg-deb -c "$deb")
for doc in $(sed -n 's/^Documentation=//p' "$src/systemd/virtualbutcherd.service"); do
  grep -q " \.${doc#file:}\$" <<<"$contents" || fail "Documentation= $doc is not in the package"
done
for f in ./usr/share/virtualbutcher/vbutcher_lcmtypes.jar ./usr/share/virtualbutcher/lamb.vbt \
         ./usr/lib/systemd/system/virtualbutcherd.service ./usr/bin/virtualbutcherd; do
  grep -q " $f\$" <<<"$contents" || fail "$f is not in the package"
done

# Install into a scratch root with its own dpkg database (dependencies are the host's).
root="$work/root"
mkdir -p "$root/var/lib/dpkg/info" "$root/var/lib/dpkg/updates"
touch "$root/var/lib/dpkg/status" "$root/var/lib/dpkg/available"
dpkg_root() { dpkg --root="$root" --force-depends --force-not-root --force-script-chrootless \
  --log=/dev/null --instdir="$root" --admindir="$root/var/lib/dpkg" "$@"; }
dpkg_root -i "$deb" >"$work/install1.log" 2>&1 || { cat "$work/install1.log"; fail "install"; }
grep -q "uri: vbrig://" "$root/etc/virtualbutcher/rig.yaml" && fail "the installed rig uses virtual cameras"
# The installed configuration is checked by the installed daemon: only this machine's lack of
# can0 (and the state folder) may be wrong.
set +e
"$root/usr/bin/virtualbutcherd" --check-config --config "$root/etc/virtualbutcher/virtualbutcherd.yaml" \
  >"$work/check.log" 2>&1
rc=$?
set -e
[ $rc = 3 ] && grep -q "can.interface: 'can0': no such network interface" "$work/check.log" &&
  ! grep -q "^<3>.*\(template\|rig\|unknown key\)" "$work/check.log" ||
  { cat "$work/check.log"; fail "the installed configuration does not check (exit $rc)"; }

# A site's edit, then an upgrade to a newer version of the same package.
sed -i 's/serial: "1111111111"/serial: "1208050080"/' "$root/etc/virtualbutcher/rig.yaml"
dpkg-deb -R "$deb" "$work/v2"
sed -i 's/^Version: .*/Version: 99.0.0/' "$work/v2/DEBIAN/control"
echo "an upgrade" >>"$work/v2/usr/share/doc/virtualbutcher/README.md"
dpkg-deb -b --root-owner-group "$work/v2" "$work/v2.deb" >/dev/null
dpkg_root -i "$work/v2.deb" >"$work/install2.log" 2>&1 || { cat "$work/install2.log"; fail "upgrade"; }
grep -q "^Version: 99.0.0" <(dpkg_root -s virtualbutcher) || fail "the upgrade did not install"
grep -q 'serial: "1208050080"' "$root/etc/virtualbutcher/rig.yaml" ||
  fail "the upgrade overwrote the site's rig.yaml"
tail -1 "$root/usr/share/doc/virtualbutcher/README.md" | grep -q "an upgrade" || fail "the upgrade did not replace files"
echo "ok: $(basename "$deb"): conffiles $(tr '\n' ' ' <<<"$conffiles"); Documentation= and the lcm-spy jar shipped; a site's rig.yaml edit survives an upgrade"
