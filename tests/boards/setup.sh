#!/usr/bin/env bash
# Sets up the emulated boards that tests/boards.rs boots, from Debian packages only:
#
#   tests/boards/setup.sh [BOARD...]     # default: vexpress-a9 x86-vesa
#
# Boards:
#   vexpress-a9   32-bit ARM (Cortex-A9), the PL111 CLCD colour LCD controller at 640x480 RGB565
#                 (Debian's armmp kernel, its vexpress-v2p-ca9 device tree with a DPI panel),
#                 a PS/2 keyboard on the PL050 KMI; stripmask for
#                 thumbv7neon-unknown-linux-gnueabihf (32-bit ARM with NEON)
#   x86-vesa      64-bit PC, VESA BIOS framebuffer (vesafb) at 800x600, 24 bits per pixel, an
#                 i8042 PS/2 keyboard; no stripmask of its own: the board is the host's
#                 architecture, and tests/it/boards.rs appends the suite's own binary with the
#                 shared libraries it loads when it boots the board
#
# For each board it leaves in $STRIPMASK_BOARDS_DIR/BOARD/ (default target/boards/BOARD/):
#   qemu-args           how to boot it, one argument per line (tests/boards.rs and run.sh read it)
#   vmlinuz, *.dtb      the kernel and the device tree
#   initramfs.cpio.gz   busybox, tests/boards/init, the keyboard modules, and for the ARM board
#                       the static stripmask
#   host-binary         (x86-vesa) says that the initramfs has no stripmask: whoever boots the
#                       board appends the host's (tests/it/boards.rs, run.sh)
# and in $STRIPMASK_BOARDS_DIR/qemu/ the QEMU system emulators (extracted from the packages, not
# installed: installing qemu-system-* would replace a newer qemu-utils on some machines).
#
# Host packages it installs with apt-get when missing (as root or through sudo):
# device-tree-compiler, gcc-arm-linux-gnueabihf and libc6-dev-armhf-cross (to link armv7), the
# run-time libraries the QEMU packages depend on. Downloads (kernels, busybox, QEMU: about 140 MB)
# go through apt-get with a private package list under $STRIPMASK_BOARDS_DIR/apt, so the
# machine's apt configuration and architectures are left alone. Rust targets come from rustup.
# Everything it makes or downloads stays under $STRIPMASK_BOARDS_DIR; running it again reuses
# what is there and rebuilds stripmask (cargo decides what changed).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
# shellcheck source=tests/boards/apt.sh
. "$here/apt.sh"
out=${STRIPMASK_BOARDS_DIR:-$root/target/boards}
profile=${STRIPMASK_BOARDS_PROFILE:-suite}
boards=("$@")
[ "${#boards[@]}" -gt 0 ] || boards=(vexpress-a9 x86-vesa)

say() { echo "boards/setup: $*" >&2; }
die() {
    say "error: $*"
    exit 1
}

for board in "${boards[@]}"; do
    case "$board" in
    vexpress-a9 | x86-vesa) ;;
    *) die "unknown board '$board' (boards: vexpress-a9 x86-vesa)" ;;
    esac
done
command -v apt-get >/dev/null || die "apt-get not found: the boards are set up from Debian packages"
command -v dpkg-deb >/dev/null || die "dpkg-deb not found"
command -v cargo >/dev/null || die "cargo not found"
if [ "$(id -u)" -eq 0 ]; then sudo=(); else sudo=(sudo); fi

wants() {
    local b
    for b in "${boards[@]}"; do [ "$b" = "$1" ] && return 0; done
    return 1
}

# Debian architecture, kernel flavour, Rust target of each board.
board_arch() { case "$1" in vexpress-a9) echo armhf ;; x86-vesa) echo amd64 ;; esac; }
board_flavour() { case "$1" in vexpress-a9) echo armmp ;; x86-vesa) echo amd64 ;; esac; }
# The Rust target of a board that needs a cross-built stripmask; none for x86-vesa.
board_target() { case "$1" in vexpress-a9) echo thumbv7neon-unknown-linux-gnueabihf ;; esac; }

mkdir -p "$out"

# --- Host packages --------------------------------------------------------------------------
install_missing() {
    local missing=() p
    for p in "$@"; do
        dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
    done
    [ "${#missing[@]}" -eq 0 ] && return 0
    say "apt-get install ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    if [ ! -e "$out/.apt-updated" ]; then
        apt_update "${sudo[@]}" apt-get
        touch "$out/.apt-updated"
    fi
    "${sudo[@]}" apt-get install -y -qq --no-install-recommends --no-upgrade "${missing[@]}" >/dev/null
}

host_packages=(device-tree-compiler)
wants vexpress-a9 && host_packages+=(gcc-arm-linux-gnueabihf libc6-dev-armhf-cross)
install_missing "${host_packages[@]}"

# --- Private apt lists: packages of other architectures without `dpkg --add-architecture` ---
apt_dir="$out/apt"
mkdir -p "$apt_dir/lists/partial" "$apt_dir/cache/archives/partial" "$out/debs"
# The release's main archive alone: emulated boards need no security updates, and fewer indexes
# are fewer to find in the middle of a mirror's sync.
cat >"$apt_dir/sources.list" <<EOF
deb [signed-by=/usr/share/keyrings/debian-archive-keyring.gpg] http://deb.debian.org/debian bookworm main
EOF
apt_opts=(
    -o "Dir::State::Lists=$apt_dir/lists"
    -o "Dir::Cache=$apt_dir/cache"
    -o "Dir::Etc::SourceList=$apt_dir/sources.list"
    -o "Dir::Etc::SourceParts=$apt_dir/no-parts"
    -o "APT::Architectures::=amd64"
    -o "APT::Architectures::=armhf"
    -o "APT::Sandbox::User=root"
    -o "Debug::NoLocking=true"
)
[ -f /usr/share/keyrings/debian-archive-keyring.gpg ] ||
    install_missing debian-archive-keyring
if [ -z "$(find "$apt_dir/lists" -name '*_Packages*' -mmin -1440 2>/dev/null | head -n 1)" ]; then
    say "apt-get update (private lists in $apt_dir)"
    apt_update apt-get "${apt_opts[@]}"
fi

# The newest version of a package, as a .deb in $out/debs; prints its path.
fetch_deb() {
    local spec=$1 name arch version file
    name=${spec%%:*}
    arch=${spec#*:}
    [ "$arch" = "$spec" ] && arch=amd64
    version=$(apt-cache "${apt_opts[@]}" show --no-all-versions "$name:$arch" 2>/dev/null |
        awk '/^Version:/ { print $2; exit }')
    [ -n "$version" ] || die "package $name:$arch not found in the Debian lists (did apt-get update reach the mirror?)"
    file=$(ls "$out/debs/${name}_"*"_$arch.deb" "$out/debs/${name}_"*"_all.deb" 2>/dev/null |
        grep -F "_${version//:/%3a}_" | head -n 1 || true)
    if [ -z "$file" ]; then
        (cd "$out/debs" && apt-get "${apt_opts[@]}" download -qq "$name:$arch") >&2 ||
            die "apt-get download $name:$arch failed"
        file=$(ls "$out/debs/${name}_${version//:/%3a}_$arch.deb" \
            "$out/debs/${name}_${version//:/%3a}_all.deb" 2>/dev/null | head -n 1)
        [ -n "$file" ] || die "apt-get download $name:$arch left no .deb"
    fi
    echo "$file"
}

# The kernel package a flavour's meta-package points at (linux-image-6.1.0-NN-FLAVOUR).
kernel_package() {
    apt-cache "${apt_opts[@]}" depends "linux-image-$1:$2" 2>/dev/null |
        awk '/Depends: linux-image-/ { sub(/:.*$/, "", $2); print $2; exit }'
}

# --- QEMU system emulators, extracted --------------------------------------------------------
qemu_dir="$out/qemu"
qemu_debs=(qemu-system-common qemu-system-data:all seabios:all)
wants vexpress-a9 && qemu_debs+=(qemu-system-arm)
wants x86-vesa && qemu_debs+=(qemu-system-x86)
libs=()
for spec in "${qemu_debs[@]}"; do
    deb=$(fetch_deb "$spec")
    stamp="$qemu_dir/.$(basename "$deb").extracted"
    if [ ! -e "$stamp" ]; then
        mkdir -p "$qemu_dir"
        dpkg-deb -x "$deb" "$qemu_dir"
        touch "$stamp"
    fi
    case "$spec" in
    qemu-system-arm | qemu-system-x86)
        # Their shared libraries, from the package's own Depends (version constraints dropped).
        while read -r lib; do libs+=("$lib"); done < <(dpkg-deb -f "$deb" Depends | tr ',' '\n' |
            sed -e 's/([^)]*)//g' -e 's/|.*//' -e 's/ //g' | grep -E '^(lib|zlib)')
        ;;
    esac
done
install_missing "${libs[@]}"
# A wrapper per emulator: the extracted QEMU looks for its modules (the TCG accelerator of x86)
# and firmware where the package would have installed them.
mkdir -p "$qemu_dir/bin"
for emulator in qemu-system-arm qemu-system-x86_64; do
    [ -x "$qemu_dir/usr/bin/$emulator" ] || continue
    missing_libs=$(ldd "$qemu_dir/usr/bin/$emulator" | awk '/not found/ { print $1 }')
    [ -z "$missing_libs" ] || die "$emulator lacks $missing_libs"
    cat >"$qemu_dir/bin/$emulator" <<EOF
#!/bin/sh
QEMU_AUDIO_DRV=none QEMU_MODULE_DIR="$qemu_dir/usr/lib/x86_64-linux-gnu/qemu" exec "$qemu_dir/usr/bin/$emulator" \\
    -L "$qemu_dir/usr/share/qemu" -L "$qemu_dir/usr/share/seabios" "\$@"
EOF
    chmod 755 "$qemu_dir/bin/$emulator"
done

# --- Busybox for the host (packs the initramfs) and for each board ---------------------------
extract_busybox() {
    local arch=$1 dir="$out/busybox-$1"
    if [ ! -x "$dir/bin/busybox" ]; then
        mkdir -p "$dir"
        dpkg-deb -x "$(fetch_deb "busybox-static:$arch")" "$dir"
    fi
    echo "$dir/bin/busybox"
}
host_busybox=$(extract_busybox amd64)

# --- stripmask, static, for each board of another architecture --------------------------------
# shellcheck source=tests/boards/cross.sh
. "$here/cross.sh"
installed_targets=$(rustup target list --installed 2>/dev/null || true)
target_args=()
for board in "${boards[@]}"; do
    target=$(board_target "$board")
    [ -n "$target" ] || continue
    if ! grep -qx "$target" <<<"$installed_targets"; then
        say "rustup target add $target"
        rustup target add "$target" >&2 || die "rustup target add $target failed"
    fi
    target_args+=(--target "$target")
done
# One cargo call for all boards: their builds share the two cores where one alone leaves a core
# idle (a crate's last steps run on one).
if [ "${#target_args[@]}" -gt 0 ]; then
    say "cargo build stripmask for ${target_args[*]} (--profile $profile, fbdev, no window)"
    (cd "$root" && cargo build --bin stripmask --quiet --profile "$profile" "${target_args[@]}" \
        -p stripmask --no-default-features --features cli,fbdev) ||
        die "building stripmask for ${target_args[*]} failed"
fi

# --- Kernels, device trees, initramfs ---------------------------------------------------------
for board in "${boards[@]}"; do
    arch=$(board_arch "$board")
    flavour=$(board_flavour "$board")
    dir="$out/$board"
    mkdir -p "$dir"
    kpkg=$(kernel_package "$flavour" "$arch")
    [ -n "$kpkg" ] || die "no linux-image-$flavour:$arch in the Debian lists"
    kdeb=$(fetch_deb "$kpkg:$arch")
    kdir="$dir/kernel"
    if [ ! -e "$kdir/.$(basename "$kdeb")" ]; then
        rm -rf "$kdir"
        mkdir -p "$kdir"
        # Only the kernel, the device trees and the input modules: the rest is not needed.
        dpkg-deb --fsys-tarfile "$kdeb" | tar -x -C "$kdir" --wildcards \
            './boot/vmlinuz-*' './usr/lib/linux-image-*/vexpress-*' \
            './lib/modules/*/kernel/drivers/input/evdev.ko' \
            './lib/modules/*/kernel/drivers/input/serio/ambakmi.ko' 2>/dev/null || true
        ls "$kdir"/boot/vmlinuz-* >/dev/null 2>&1 || die "no kernel in $kdeb"
        touch "$kdir/.$(basename "$kdeb")"
    fi
    cp "$kdir"/boot/vmlinuz-* "$dir/vmlinuz"
    version=$(basename "$(ls -d "$kdir"/lib/modules/*)")

    root_dir="$dir/rootfs"
    rm -rf "$root_dir"
    mkdir -p "$root_dir"/{bin,usr/bin,lib/modules,proc,sys,dev,data,tmp}
    cp "$(extract_busybox "$arch")" "$root_dir/bin/busybox"
    cp "$here/init" "$root_dir/init"
    chmod 755 "$root_dir/init"
    target=$(board_target "$board")
    if [ -n "$target" ]; then
        cp "$root/target/$target/$profile/stripmask" "$root_dir/usr/bin/stripmask"
        # Without its symbols the binary is a fifth smaller: a faster boot.
        arm-linux-gnueabihf-strip "$root_dir/usr/bin/stripmask"
        rm -f "$dir/host-binary"
    else
        echo "the initramfs has no stripmask: append the host's with its shared libraries" >"$dir/host-binary"
    fi
    modules=(drivers/input/evdev.ko)
    case "$board" in
    vexpress-a9)
        # The PL050 KMI the keyboard hangs off is a module; the keyboard driver (atkbd) is built in.
        modules+=(drivers/input/serio/ambakmi.ko)
        dtb_in=$(ls "$kdir"/usr/lib/linux-image-*/vexpress-v2p-ca9.dtb)
        dtb="$dir/vexpress-v2p-ca9-lcd.dtb"
        cp "$dtb_in" "$dtb"
        # The coretile's PL111 drives the DVI transmitter, for which the kernel has no driver in
        # this role: describe it as a 640x480 DPI panel (VGA timings, 25.175 MHz), which the
        # built-in PL111 framebuffer driver (CONFIG_FB_ARMCLCD) reads; its memory bandwidth
        # limit then picks 16 bits per pixel, RGB565. The motherboard's second CLCD, wired to the
        # same transmitter, is switched off.
        mb=/bus@40000000/motherboard-bus@40000000/iofpga@7,00000000
        panel=$mb/i2c@16000/dvi-transmitter@39
        fdtget "$dtb" "$panel" compatible >/dev/null 2>&1 ||
            die "$dtb_in has no $panel: the device tree changed, update setup.sh"
        fdtput -t s "$dtb" "$panel" compatible panel-dpi
        fdtput -c "$dtb" "$panel/panel-timing"
        for kv in clock-frequency=25175000 hactive=640 vactive=480 hfront-porch=16 \
            hback-porch=48 hsync-len=96 vfront-porch=10 vback-porch=33 vsync-len=2; do
            fdtput -t u "$dtb" "$panel/panel-timing" "${kv%%=*}" "${kv#*=}"
        done
        fdtput -t s "$dtb" "$mb/clcd@1f000" status disabled
        cat >"$dir/qemu-args" <<EOF
$qemu_dir/bin/qemu-system-arm
-M
vexpress-a9
-m
256M
-kernel
$dir/vmlinuz
-dtb
$dtb
-append
console=ttyAMA0 panic=-1 quiet
EOF
        ;;
    x86-vesa)
        cat >"$dir/qemu-args" <<EOF
$qemu_dir/bin/qemu-system-x86_64
-M
pc
-m
256M
-vga
std
-kernel
$dir/vmlinuz
-append
console=ttyS0 vga=0x315 panic=-1 quiet
EOF
        ;;
    esac
    for m in "${modules[@]}"; do
        cp "$kdir/lib/modules/$version/kernel/$m" "$root_dir/lib/modules/"
    done
    (cd "$root_dir" && find . | LC_ALL=C sort | "$host_busybox" cpio -o -H newc 2>/dev/null) |
        gzip -9 >"$dir/initramfs.cpio.gz"
    say "$board ready: $dir ($(du -h "$dir/initramfs.cpio.gz" | cut -f1) initramfs, kernel $version)"
done
