#!/usr/bin/env bash
# The scale table of docs/scale.md: the same terrain under the same flight, in models of growing
# size. Each model is SIDE x SIDE samples made by mirror-tiling the bundled Puget Sound map
# (examples/mirror_model.rs), 40 m apart, 0.1 m per unit, in tiles of 65; for each one this
# builds the archive in tiles of 65 and of 129 (wall time, peak memory, cores used), reads what
# an open reads, and flies benches/scale-flight.toml on the simulated clock as the PocketPC
# (320x240, 20 MB, 1 Mbit/s), the workstation (1280x720, 256 MB) and `native` (the PocketPC's
# screen and memory with this machine's CPU: τ = 1 px binds, not the budget, which gives the
# triangles per pixel a view needs). One markdown row per model, tile size and profile on
# stdout; the models, archives and flights stay in $WORK (default /tmp/stripmask-scale),
# nothing in the repository.
#
#   bash benches/scale.sh                 # 1025 4097 16385 32769
#   bash benches/scale.sh 1025 4097       # the small ones only
#
# Disk: the raw model of 32769² takes 2.1 GB and its archive about 5 GB.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${WORK:-/tmp/stripmask-scale}
mkdir -p "$work"
if [ "$#" -gt 0 ]; then sides=("$@"); else sides=(1025 4097 16385 32769); fi

cargo build --release --quiet --bin stripmask --example mirror_model
bin=target/release/stripmask
flight=benches/scale-flight.toml

# `/usr/bin/time -v` figures of a finished command: peak resident memory (MB), wall seconds,
# and cores used (user + system time over wall time).
rss_mb() { awk -F': ' '/Maximum resident/ {printf "%.0f", $2 / 1024}' "$1"; }
wall_s() {
    awk -F': ' '/Elapsed \(wall clock\)/ {
        n = split($2, p, ":"); s = 0; for (i = 1; i <= n; i++) s = s * 60 + p[i]; printf "%.1f", s
    }' "$1"
}
cores() {
    awk -F': ' '/User time/ {u = $2} /System time/ {s = $2} /Elapsed \(wall clock\)/ {
        n = split($2, p, ":"); w = 0; for (i = 1; i <= n; i++) w = w * 60 + p[i]
    } END {printf "%.2f", (u + s) / (w > 0 ? w : 1)}' "$1"
}

echo "| model | tiles | build | build memory | cores | archive | open reads | profile | first frame | first hole-free | pager peak | process peak | bookkeeping | paging | median fps | error mean / max | error mean after 10 s | tiles drawn | triangles / pixel |"
echo "| --- | --- | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
for side in "${sides[@]}"; do
    raw="$work/puget$side.r16"
    [ -f "$raw" ] || target/release/examples/mirror_model "$side" "$raw"
    for tile in 65 129; do
        archive="$work/puget$side-$tile.smdb"
        if [ ! -f "$archive" ]; then
            /usr/bin/time -v "$bin" build "$raw" -o "$archive" --width "$side" --height "$side" \
                --sample-type u16 --spacing 40 --vertical-scale 0.1 --tile-size "$tile" --quiet \
                2>"$archive.time"
        fi
        info=$("$bin" info --json "$archive")
        opening=$(jq -r .opening_bytes <<<"$info")
        tiles=$(jq -r '.pyramid[0] | "\(.[0]) x \(.[1])"' <<<"$info")
        bytes=$(stat -c %s "$archive")
        for profile in pocketpc workstation native; do
            out="$work/fly-$side-$tile-$profile"
            /usr/bin/time -v "$bin" fly "$archive" --profile "$profile" --clock simulated \
                --flight "$flight" --out "$out" --quiet --no-plots >"$out.txt" 2>"$out.time"
            summary=$(head -1 "$out.txt")
            holes=$(sed -n 2p "$out.txt")
            drawn=$(sed -n 3p "$out.txt")
            fps=$(grep -oP 'median \K[0-9.]+(?= fps)' <<<"$summary")
            error=$(grep -oP 'screen error max \K[0-9.]+ / mean [0-9.]+' <<<"$summary" |
                awk '{print $4 " / " $1}')
            peak=$(grep -oP 'peak memory \K[0-9.]+' <<<"$summary")
            first=$(grep -oP 'first frame at \K[0-9.]+ s|first frame at never' <<<"$holes")
            full=$(grep -oP 'first without a hole at \K([0-9.]+ s|never)' <<<"$holes")
            mean_tiles=$(grep -oP 'drawn: \K[0-9.]+' <<<"$drawn")
            per_pixel=$(grep -oP '[0-9.]+(?= triangles per pixel)' <<<"$drawn")
            bookkeeping=$(grep -oP 'median \K[0-9.]+(?= ms of bookkeeping)' <<<"$drawn")
            paging=$(grep -oP '[0-9.]+(?= ms of paging)' <<<"$drawn")
            # The mean past the first 10 s: what the view costs once the chain of tiles from
            # the top down to the eye has arrived (the start grows with the pyramid's depth).
            settled=$(awk -F, 'NR == 1 {for (i = 1; i <= NF; i++) if ($i == "error_px") c = i; next}
                $2 >= 10 {s += $c; n++} END {printf "%.2f", n ? s / n : 0}' "$out/stats.csv")
            build="-"
            [ -f "$archive.time" ] && build="$(wall_s "$archive.time") s"
            bmem="-"
            [ -f "$archive.time" ] && bmem="$(rss_mb "$archive.time") MB"
            bcores="-"
            [ -f "$archive.time" ] && bcores=$(cores "$archive.time")
            echo "| ${side}², tiles of $tile | $tiles | $build | $bmem | $bcores | $(awk "BEGIN {printf \"%.1f MB\", $bytes / 1e6}") | $opening B | $profile | $first | $full | $peak MB | $(rss_mb "$out.time") MB | $bookkeeping ms | $paging ms | $fps | $error px | $settled px | $mean_tiles | $per_pixel |"
        done
    done
done
