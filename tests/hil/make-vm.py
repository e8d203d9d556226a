#!/usr/bin/env python3
"""Builds the small VM the CAN hardware-in-loop test boots: Debian's own kernel (unpacked
to an ELF vmlinux, which qemu boots directly via PVH, skipping the in-guest decompression
that is slow under software emulation) and a busybox initramfs that loads the CAN, vcan,
can-gw and 9p modules, mounts the host's root read-only and runs the test script given on
the kernel command line in a chroot of it.

Usage: make-vm.py KERNEL_DEB OUT_DIR
Writes OUT_DIR/vmlinux and OUT_DIR/initramfs.cpio.gz. Needs busybox-static."""
import gzip
import io
import lzma
import os
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

MODULES = ["vcan", "can-raw", "can-gw", "9p", "9pnet_virtio", "virtio_pci"]

INIT = r"""#!/bin/busybox sh
/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
for m in $(cat /modules.order); do insmod /modules/$m.ko || echo "vm: insmod $m failed"; done
mkdir -p /host
mount -t 9p -o trans=virtio,version=9p2000.L,ro hostroot /host || echo "vm: no 9p host root"
for d in proc sys dev; do mount --bind /$d /host/$d; done
mount -t tmpfs run /host/run  # the only writable place; the host's /tmp stays visible
script=$(sed -n 's/.*vbtest=\([^ ]*\).*/\1/p' /proc/cmdline)
args=$(sed -n 's/.*vbargs=\([^ ]*\).*/\1/p' /proc/cmdline | tr ',' ' ')
echo "vm: running $script $args"
chroot /host /bin/bash "$script" $args
echo "vm: exit status $?"
poweroff -f
"""


def modinfo_depends(path):
    data = path.read_bytes()
    key = b"\x00depends="
    i = data.find(key)
    if i < 0:
        return []
    end = data.index(b"\x00", i + 1)
    value = data[i + len(key):end].decode()
    return [d for d in value.split(",") if d]


def extract_vmlinux(vmlinuz, out):
    data = vmlinuz.read_bytes()
    for magic, decompress in ((b"\xfd7zXZ\x00", lambda b: lzma.LZMADecompressor().decompress(b)),
                              (b"\x1f\x8b\x08", lambda b: gzip.GzipFile(fileobj=io.BytesIO(b)).read())):
        i = data.find(magic)
        while i >= 0:
            try:
                elf = decompress(data[i:])
                if elf[:4] == b"\x7fELF":
                    out.write_bytes(elf)
                    return
            except Exception:
                pass
            i = data.find(magic, i + 1)
    sys.exit(f"{vmlinuz}: no compressed ELF kernel found inside")


def main():
    deb, out = Path(sys.argv[1]), Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        subprocess.run(["dpkg-deb", "-x", str(deb), str(tmp / "deb")], check=True)
        kernel_dir = next((tmp / "deb/lib/modules").iterdir())
        extract_vmlinux(next((tmp / "deb/boot").glob("vmlinuz-*")), out / "vmlinux")
        by_name = {p.name[:-3].replace("_", "-"): p for p in kernel_dir.rglob("*.ko")}

        def find(name):
            return by_name[name.replace("_", "-")]

        order, seen = [], set()

        def visit(name):
            key = name.replace("_", "-")
            if key in seen:
                return
            seen.add(key)
            for dep in modinfo_depends(find(name)):
                visit(dep)
            order.append(key)

        for m in MODULES:
            visit(m)
        root = tmp / "initramfs"
        for d in ("bin", "proc", "sys", "dev", "modules", "tmp"):
            (root / d).mkdir(parents=True)
        busybox = Path("/bin/busybox")
        (root / "bin/busybox").write_bytes(busybox.read_bytes())
        (root / "bin/busybox").chmod(0o755)
        for m in order:
            (root / "modules" / f"{m}.ko").write_bytes(find(m).read_bytes())
        (root / "modules.order").write_text("\n".join(order) + "\n")
        (root / "init").write_text(INIT)
        (root / "init").chmod(0o755)
        files = subprocess.run(["find", "."], cwd=root, check=True, capture_output=True).stdout
        cpio = subprocess.run(["/bin/busybox", "cpio", "-o", "-H", "newc"], cwd=root, input=files,
                              check=True, capture_output=True).stdout
        (out / "initramfs.cpio.gz").write_bytes(gzip.compress(cpio))
        print(f"make-vm: {out}/vmlinux, {out}/initramfs.cpio.gz; modules: {' '.join(order)}")


if __name__ == "__main__":
    main()
