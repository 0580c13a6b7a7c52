#!/usr/bin/env bash
# Output checksums of every stage on testdata/ and the real frames in ../shared/data, through the
# CLI: filter outputs, plane labels + plane parameters (JSON), motion JSON, fused meshes, simulated
# frames. Used to show a refactor changes no output: run it with the binary before and after and
# diff the two listings.
#
#   docs/bench/checksums.sh path/to/sldepth > sums.txt
set -euo pipefail
bin=${1:?usage: checksums.sh SLDEPTH_BINARY}
root=$(cd "$(dirname "$0")/../.." && pwd)
data=${SLDEPTH_DATA:-$root/../shared/data}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

sum() { sha256sum "$1" | cut -c1-16; }
run() { # name, then the command; prints name and the checksum of every file it wrote
    local name=$1; shift
    rm -rf "$out/o"; mkdir -p "$out/o"
    if "$@" > "$out/o/stdout.txt" 2> "$out/o/stderr.txt"; then
        # Timing fields vary run to run; drop them before hashing stdout.
        sed "s#$out#OUT#g" "$out/o/stdout.txt" | python3 "$root/docs/bench/strip_timing.py" > "$out/o/stdout.json"
        rm "$out/o/stdout.txt" "$out/o/stderr.txt"
        local g; for g in $(ls "$out/o" | sort); do printf '%-48s %-14s %s\n' "$name" "$g" "$(sum "$out/o/$g")"; done
    else
        printf '%-48s FAILED: %s\n' "$name" "$(head -c 200 "$out/o/stderr.txt")"
    fi
}

frames=()
for f in "$root"/testdata/*-depth.png; do frames+=("$f:1000:"); done
if [ -d "$data" ]; then
    frames+=("$data/open3d-testdata/person-depth.png:1000:")
    frames+=("$data/open3d-testdata/tum-depth.png:5000:")
    frames+=("$data/open3d-testdata/nyu-raw-disparity.pgm::")
    frames+=("$data/tum-fr1-rpy-200/depth/$(ls "$data/tum-fr1-rpy-200/depth" | sed -n 1p):5000:")
    frames+=("$data/tum-fr1-rpy-200/depth/$(ls "$data/tum-fr1-rpy-200/depth" | sed -n 120p):5000:")
    frames+=("$data/7scenes-redkitchen/frame-000150.depth.png:1000:")
    frames+=("$data/pcl-floor-box/$(ls "$data/pcl-floor-box" | grep -i tif | sed -n 1p):1000:")
fi

for spec in "${frames[@]}"; do
    IFS=: read -r f scale _ <<< "$spec"
    [ -f "$f" ] || continue
    n=$(basename "$f")
    s=(); [ -n "$scale" ] && s=(--depth-scale "$scale")
    for m in adaptive bilateral gaussian disparity; do
        run "filter-$m $n" "$bin" filter "$f" "$out/o/out.png" --normals "$out/o/normals.png" --method "$m" "${s[@]}"
    done
    # The multi-scale filter explicitly (every version since it exists), and the single pass of
    # the default method (a flag added when the multi-scale filter became the default).
    run "filter-multiscale $n" "$bin" filter "$f" "$out/o/out.png" --multiscale "${s[@]}"
    if "$bin" filter --help | grep -q -- --single-scale; then
        run "filter-adaptive-single $n" "$bin" filter "$f" "$out/o/out.png" --single-scale "${s[@]}"
    fi
    run "planes $n" "$bin" planes "$f" --output "$out/o/labels.png" --overlay "$out/o/overlay.png" --json "${s[@]}"
    run "planes-ransac $n" "$bin" planes "$f" --method metric-ransac --output "$out/o/labels.png" --json "${s[@]}"
    run "cloud $n" "$bin" cloud "$f" --output "$out/o/cloud.ply" "${s[@]}"
    run "analyze $n" "$bin" analyze "$f" --json "${s[@]}"
done

if [ -d "$data/tum-fr1-rpy" ]; then
    d=$(ls "$data/tum-fr1-rpy/depth" | sort)
    a=$data/tum-fr1-rpy/depth/$(echo "$d" | sed -n 1p)
    for k in 6 11 16; do
        b=$data/tum-fr1-rpy/depth/$(echo "$d" | sed -n ${k}p)
        run "motion 1-$k" "$bin" motion "$a" "$b" --depth-scale 5000 --json
        run "motion-icp 1-$k" "$bin" motion "$a" "$b" --depth-scale 5000 --icp --json
    done
fi
if [ -d "$data/7scenes-redkitchen" ]; then
    run "fuse 7scenes-10" "$bin" fuse --7scenes "$data/7scenes-redkitchen" --max-frames 10 --output "$out/o/mesh.ply" --json
fi
if [ -d "$data/tum-fr1-rpy" ]; then
    run "fuse tum-5" "$bin" fuse --tum "$data/tum-fr1-rpy" --max-frames 5 --prefilter --output "$out/o/mesh.ply" --json
fi
if [ -d "$data/open3d-testdata/icl-livingroom" ]; then
    icl=$data/open3d-testdata/icl-livingroom
    run "fuse icl" "$bin" fuse --depth-dir "$icl/depth" --o3d-log "$icl/odometry.log" --camera "$icl/camera.json" --output "$out/o/mesh.ply" --slice-png "$out/o/slice.png" --slice-m 1.0 --render-png "$out/o/render.png" --json
fi
for scene in floor three-planes figure-walls; do
    run "simulate $scene" "$bin" simulate --scene "$scene" --seed 5 --output "$out/o/depth.png" --truth "$out/o/truth.png" --labels "$out/o/labels.png"
done
