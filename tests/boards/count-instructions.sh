#!/usr/bin/env bash
# Instructions per frame on each CPU, counted by a QEMU TCG plugin (tests/boards/insn-count.c)
# under user-mode emulation. A count, not a time: emulation says nothing about how fast a real
# core runs these instructions. docs/platforms.md has the figures and what they mean for real
# cores.
#
#   tests/boards/count-instructions.sh [FRAMES]      # default 10
#   STRIPMASK_COUNT=raster|engine tests/boards/count-instructions.sh   # one part only
#   STRIPMASK_COUNT_TARGETS="armv5te-unknown-linux-gnueabi" ...        # the engine on some CPUs
#
# raster: the rasterizer's PocketPC frame (raster/examples/pocketpc_frames.rs: 320x240 RGB565,
#   16-bit depth, 10,082 textured and shaded triangles, one thread) on x86-64, aarch64, 32-bit
#   ARM with NEON and ARMv5TE soft float run as the XScale PXA255 (`qemu-arm -cpu pxa255`), then
#   the same scene at 800x480 on 32-bit ARM with NEON. Each runs with 0 and FRAMES frames and
#   prints (count(FRAMES) - count(0)) / FRAMES: the scene's set-up cancels out.
# engine: the whole engine, the demo's PocketPC flight (`stripmask demo` builds the archive;
#   `stripmask fly ARCHIVE --profile pocketpc --clock simulated --frames N --every 0`, no PNGs)
#   on x86-64, 32-bit ARM with NEON and the PXA255, frames 200 to 300: (count(300) -
#   count(200)) / 100, split by the plugin (kinds=FILE) into the rasterizer (the functions of
#   stripmask_raster and the library code they call) and the rest, the rest by module, and the
#   functions with the most instructions of their own on the PXA255.
# Everything is built with the release profile (`--no-default-features --features cli` for
# stripmask: the command with no window).
# Needs the packages of arm-tests.sh, a C compiler, c++filt (binutils), and Debian's qemu-user
# package (which loads plugins; qemu-user-static cannot), downloaded and extracted under
# target/boards/qemu-user.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
frames=${1:-10}
parts=${STRIPMASK_COUNT:-raster,engine}
out=${STRIPMASK_BOARDS_DIR:-$root/target/boards}
target_dir=${CARGO_TARGET_DIR:-$root/target}
say() { echo "count-instructions: $*" >&2; }

qemu_user="$out/qemu-user"
if [ ! -x "$qemu_user/usr/bin/qemu-arm" ]; then
    mkdir -p "$qemu_user/debs"
    (cd "$qemu_user/debs" && apt-get -o APT::Sandbox::User=root download -qq qemu-user)
    dpkg-deb -x "$qemu_user"/debs/qemu-user_*.deb "$qemu_user"
fi
plugin="$out/libinsn-count.so"
cc -shared -fPIC -O2 -o "$plugin" "$here/insn-count.c"

# shellcheck source=tests/boards/cross.sh
. "$here/cross.sh"
cd "$root"

# The emulator of a target, with the CPU it is counted on.
emulator() {
    case "$1" in
    x86_64-*) echo "$qemu_user/usr/bin/qemu-x86_64" ;;
    thumbv7neon-*) echo "$qemu_user/usr/bin/qemu-arm" ;;
    armv5te-*) echo "$qemu_user/usr/bin/qemu-arm -cpu pxa255" ;;
    aarch64-*) echo "$qemu_user/usr/bin/qemu-aarch64" ;;
    esac
}
# The name a table gives a target.
cpu() {
    case "$1" in
    x86_64-*) echo x86-64 ;;
    thumbv7neon-*) echo "armv7 NEON" ;;
    armv5te-*) echo "PXA255 (ARMv5TE)" ;;
    aarch64-*) echo aarch64 ;;
    esac
}
# Runs `BINARY ARGS...` of TARGET under the counting plugin (with OPTIONS, e.g. ,kinds=FILE) and
# prints what the plugin says; the program's own output is dropped.
counted() {
    local target=$1 options=$2 binary=$3
    shift 3
    local -a run
    read -r -a run <<<"$(emulator "$target")"
    { "${run[@]}" -plugin "$plugin$options" -d plugin "$binary" "$@" >/dev/null; } 2>&1
}
total() { awk '/^guest instructions:/ { print $3 }'; }
# Writes to FILE the kinds of BINARY's functions for the plugin: "r NAME" for the rasterizer's,
# "e NAME" for the rest of stripmask's. The kind is the crate that begins the demangled name, or
# for an impl on a type of no crate the trait's (`<u16 as stripmask_raster::sampler::Texel>::lerp`
# is the rasterizer's); library code instantiated for a closure of ours is the closure's crate's
# (`<Map<Range<usize>, stripmask::engine::resident::normals::{closure#1}>>::fold` is the
# normals' loop), any other library code is shared (`<Vec<stripmask_raster::Vertex>>::push`
# counts for its caller).
kinds() {
    local binary=$1 file=$2
    nm --defined-only "$binary" | awk '$2 ~ /^[tTwW]$/ && $3 !~ /^\$/ { print $3 }' | sort -u >"$file.names"
    sed 's/\.llvm\.[0-9]*$//' "$file.names" | c++filt | sed 's/\[[0-9a-f]*\]//g' |
        paste - "$file.names" | awk -F '\t' '{
            crate = $1
            sub(/^[<&]*/, "", crate); sub(/::.*/, "", crate); sub(/.* as [<&]*/, "", crate)
            if (crate !~ /^stripmask/ && match($1, /stripmask[a-z_]*::[^<>,; ]*[{]closure/)) {
                crate = substr($1, RSTART, RLENGTH); sub(/::.*/, "", crate)
            }
            if (crate == "stripmask_raster") print "r", $2
            else if (crate == "stripmask" || crate == "stripmask_platform") print "e", $2
        }' >"$file"
}

if [[ ",$parts," == *,raster,* ]]; then
    echo "the rasterizer's PocketPC frame, $frames frames"
    for target in x86_64-unknown-linux-gnu aarch64-unknown-linux-musl \
        thumbv7neon-unknown-linux-gnueabihf armv5te-unknown-linux-gnueabi; do
        cross_cargo build "$target" --quiet --release -p stripmask-raster --example pocketpc_frames
        binary="$target_dir/$target/release/examples/pocketpc_frames"
        sizes=("320x240")
        [ "${target%%-*}" != thumbv7neon ] || sizes+=("800x480")
        for size in "${sizes[@]}"; do
            scene=$(counted "$target" "" "$binary" 0 --size "$size" | total)
            all=$(counted "$target" "" "$binary" "$frames" --size "$size" | total)
            read -r -a run <<<"$(emulator "$target")"
            picture=$("${run[@]}" "$binary" 1 --size "$size" | sed 's/.*picture //')
            awk -v t="$(cpu "$target"), $size" -v s="$scene" -v a="$all" -v n="$frames" \
                -v p="$picture" 'BEGIN {
                printf "  %-28s %6.2fM instructions per frame (scene %.1fM), picture %s\n",
                    t, (a - s) / n / 1e6, s / 1e6, p }'
        done
    done
fi

if [[ ",$parts," == *,engine,* ]]; then
    work="$out/count-engine"
    mkdir -p "$work"
    read -r -a targets <<<"${STRIPMASK_COUNT_TARGETS:-x86_64-unknown-linux-gnu thumbv7neon-unknown-linux-gnueabihf armv5te-unknown-linux-gnueabi}"
    for target in "${targets[@]}"; do
        cross_cargo build "$target" --quiet --release -p stripmask --no-default-features --features cli --bin stripmask
    done
    archive="$work/demo/puget.smdb"
    if [ ! -f "$archive" ]; then
        cross_cargo build x86_64-unknown-linux-gnu --quiet --release -p stripmask --no-default-features --features cli --bin stripmask
        "$target_dir/x86_64-unknown-linux-gnu/release/stripmask" demo --out "$work/demo" --frames 1 --every 0 -q >/dev/null
    fi
    for target in "${targets[@]}"; do
        kinds "$target_dir/$target/release/stripmask" "$work/$target.kinds"
        for n in 200 300; do
            say "$(cpu "$target"): the flight's first $n frames"
            counted "$target" ",kinds=$work/$target.kinds" "$target_dir/$target/release/stripmask" fly "$archive" \
                --profile pocketpc --clock simulated --frames "$n" --every 0 --no-plots -q \
                --out "$work/fly-$target" >"$work/$target-$n.txt"
        done
    done
    echo
    echo "the whole engine: the demo's PocketPC flight, frames 200 to 300, instructions per frame"
    echo "(raster: stripmask_raster's functions and the library code they call; rest: the others')"
    printf '  %-28s %9s %9s %9s\n' CPU total raster rest
    for target in "${targets[@]}"; do
        awk -v t="$(cpu "$target")" '
            /^guest instructions:/ { all[FILENAME] = $3 }
            $1 == "symbol" && $2 == "r" { raster[FILENAME] += $3 }
            END {
                a = ARGV[1]; b = ARGV[2]
                n = (all[b] - all[a]) / 100; r = (raster[b] - raster[a]) / 100
                printf "  %-28s %8.2fM %8.2fM %8.2fM (raster %.0f%%)\n", t, n / 1e6, r / 1e6,
                    (n - r) / 1e6, 100 * r / n }' \
            "$work/$target-200.txt" "$work/$target-300.txt"
    done
    # By module: a function's own instructions and those of the library code it called, grouped
    # by the first three parts of the first stripmask path in its name (stripmask::engine::paging,
    # ...; a library loop of our closure by the closure's).
    echo
    echo "where the rest goes, by module (instructions per frame; x86-64 / armv7 NEON / PXA255)"
    for target in "${targets[@]}"; do
        for n in 200 300; do
            awk '$1 == "symbol" && $2 == "e" { print $3 " " $5 }' "$work/$target-$n.txt" |
                c++filt | sed 's/\[[0-9a-f]*\]//g' | awk -v n="$n" -v t="$target" '{
                    name = $2; for (i = 3; i <= NF; i++) name = name " " $i
                    if (match(name, /stripmask[a-z_]*::[^<>,; ]*/)) name = substr(name, RSTART, RLENGTH)
                    k = split(name, part, "::")
                    group = part[1]; for (i = 2; i <= 3 && i < k; i++) group = group "::" part[i]
                    print t, n, group, $1 }'
        done
    done | awk -v targets="${targets[*]}" '
        { sum[$1 " " $3] += ($2 == 300 ? $4 : -$4); groups[$3] = 1 }
        END {
            nt = split(targets, t, " ")
            for (g in groups) {
                line = sprintf("  %-44s", g)
                for (i = 1; i <= nt; i++) line = line sprintf(" %8.2fM", sum[t[i] " " g] / 100 / 1e6)
                print sum[t[nt] " " g] / 100, line
            }
        }' | sort -g -r | awk '$1 >= 50000 { sub(/^[^ ]* /, ""); print }'
    [[ " ${targets[*]} " == *" armv5te-unknown-linux-gnueabi "* ]] || exit 0
    echo
    echo "the most instructions of their own on the PXA255, per frame (s: shared code, counted above for its caller)"
    awk '$1 == "symbol" {
            own = (FILENAME ~ /-300\.txt$/ ? $4 : -$4); name = $5
            for (i = 6; i <= NF; i++) name = name " " $i
            self[$2 " " name] += own }
        END { for (k in self) if (self[k] >= 2000000) print self[k] / 100, k }' \
        "$work/armv5te-unknown-linux-gnueabi-200.txt" "$work/armv5te-unknown-linux-gnueabi-300.txt" |
        sort -g -r | awk 'NR <= 25' | c++filt | sed 's/\[[0-9a-f]*\]//g' |
        awk '{ name = $3; for (i = 4; i <= NF; i++) name = name " " $i
            printf "  %7.2fM %s %s\n", $1 / 1e6, $2, substr(name, 1, 110) }'
fi
