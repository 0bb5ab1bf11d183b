#!/usr/bin/env bash
# The device campaign on a CUDA machine that has Python 3.12, numpy and pytest but no Warp and no
# package index, reached by commands that each carry at most 64 MiB of files. Three verbs:
#
#   bash bench/gpu-run.sh pack [PYTHON]   here, once: Warp in two halves (.wp1/, .wp2/) and the
#                                         wheels below for CPython 3.12 (.whl/); all git-ignored
#   bash bench/gpu-run.sh first           on the device, carrying .wp1: keeps the first half
#   bash bench/gpu-run.sh campaign [S]    on the device, carrying .wp2 and .whl: unpacks Warp
#                                         and the wheels into /tmp/site and runs the campaign in
#                                         S seconds (default 500) into $OUT/campaign (else
#                                         results/campaign-gpu), then packs it as campaign.tar.xz
#   bash bench/gpu-run.sh dry-run [S]     here, after pack: both device commands from a clean
#                                         clone of HEAD, in a fresh Python 3.12 venv holding only
#                                         numpy and pytest, on the CPU with --tiny, into
#                                         results/campaign-dry-run (S seconds, default 900)
#
# On any CUDA machine with a package index none of this is needed:
#   pip install -e ".[test]" && python -m warpvol.bench.campaign --device cuda --budget 540 --out results/campaign-gpu
#
# The halves leave out Warp's CPU compiler (warp-clang.so, the larger part of the package): on the
# device the kernels compile for CUDA only, tests pinned to the CPU skip (WARPVOL_TEST_DEVICES=cuda).
set -euo pipefail
cd "$(dirname "$0")/.."

#: What the campaign imports beyond numpy and pytest, pinned (pure Python except OpenEXR and
#: flip-evaluator, the accuracy rows' second measure);
#: pyvista, Dask, Mitsuba and miepython are left behind: their tests skip.
WHEELS=(tqdm==4.70.1 OpenEXR==3.5.3 hypothesis==6.170.17 sortedcontainers==2.4.0
        pytest-benchmark==5.3.1 py-cpuinfo2==10.1.1 flip-evaluator==1.7)
SITE=${WARPVOL_SITE:-/tmp/site}
DEVICE=${WARPVOL_CAMPAIGN_DEVICE:-cuda}

case "${1:-}" in
pack)
    py=${2:-.venv/bin/python}
    src=$("$py" -c 'import os, warp; print(os.path.dirname(warp.__file__))')
    rm -rf .wp1 .wp2 .whl && mkdir -p .wp1 .wp2 .whl
    tmp=$(mktemp -d)
    echo "packing warp $("$py" -c 'import warp; print(warp.__version__)') from $src (xz -9: minutes)" >&2
    tar -C "$(dirname "$src")" --exclude='warp/bin/warp-clang.so' --exclude='warp/tests' --exclude='warp/examples' \
        --exclude='__pycache__' -cf - warp | xz -T2 -9 > "$tmp/warp.tar.xz"
    size=$(stat -c %s "$tmp/warp.tar.xz")
    split -b $(( (size + 1) / 2 + 1 )) -d "$tmp/warp.tar.xz" "$tmp/part-"
    mv "$tmp/part-00" .wp1/ && mv "$tmp/part-01" .wp2/ && rm -rf "$tmp"
    "$py" -m pip download --quiet --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
        -d .whl "${WHEELS[@]}"
    du -sh .wp1 .wp2 .whl >&2
    ;;
first)
    mkdir -p .wpk && cp .wp1/* .wpk/
    echo "first half kept in .wpk; now: bash bench/gpu-run.sh campaign (carrying .wp2 and .whl)"
    ;;
campaign)
    budget=${2:-500}
    [ -f .wpk/part-00 ] || { echo "no .wpk/part-00: run 'bash bench/gpu-run.sh first' (carrying .wp1) before" >&2; exit 2; }
    cp .wp2/* .wpk/
    mkdir -p "$SITE"
    cat .wpk/part-* | xz -d | tar -x -C "$SITE"
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$SITE" .whl/*.whl
    # warpvol from this checkout, bench/ and viz/ importing as warpvol.bench and warpvol.viz
    export PYTHONPATH="$SITE:$PWD/bench/device_site"
    out=${OUT:+$OUT/campaign}
    out=${out:-results/campaign-gpu}
    python3 -c 'import warp as wp; wp.init(); print("warp", wp.config.version, [str(d) for d in wp.get_cuda_devices()])'
    export WARPVOL_CAMPAIGN_VIA=${WARPVOL_CAMPAIGN_VIA:-"bash bench/gpu-run.sh campaign $budget"}
    status=0
    # shellcheck disable=SC2086  # WARPVOL_CAMPAIGN_ARGS: extra words, e.g. --tiny
    python3 -m warpvol.bench.campaign --device "$DEVICE" --budget "$budget" --out "$out" ${WARPVOL_CAMPAIGN_ARGS:-} || status=$?
    tar -C "$(dirname "$out")" -cJf "$(dirname "$out")/campaign.tar.xz" "$(basename "$out")"
    exit $status
    ;;
dry-run)
    budget=${2:-900}
    for d in .wp1 .wp2 .whl; do [ -d $d ] || { echo "no $d: run 'bash bench/gpu-run.sh pack' first" >&2; exit 2; }; done
    py312=
    for py in python3.12 "$HOME"/.pyenv/versions/3.12*/bin/python3.12; do  # on PATH or under pyenv
        if "$py" -c 'import sys; assert sys.version_info[:2] == (3, 12)' 2>/dev/null; then py312=$py; break; fi
    done
    [ -n "$py312" ] || { echo "the dry run needs Python 3.12 (the device's), on PATH or under pyenv" >&2; exit 2; }
    here=$PWD
    tmp=$(mktemp -d)
    git clone -q "$here" "$tmp/repo"
    cp -r .wp1 .wp2 .whl "$tmp/repo/"
    "$py312" -m venv "$tmp/venv"
    "$tmp/venv/bin/python" -m pip install -q numpy pytest
    # the CPU compiler the halves leave out, from the Warp the halves were packed from
    clang=$(.venv/bin/python -c 'import os, warp; print(os.path.join(os.path.dirname(warp.__file__), "bin", "warp-clang.so"))')
    (cd "$tmp/repo" && PATH="$tmp/venv/bin:$PATH" bash bench/gpu-run.sh first)
    mkdir -p "$tmp/site/warp/bin" && cp "$clang" "$tmp/site/warp/bin/"
    status=0
    (cd "$tmp/repo" && PATH="$tmp/venv/bin:$PATH" WARPVOL_SITE="$tmp/site" WARPVOL_CAMPAIGN_DEVICE=cpu \
        WARPVOL_CAMPAIGN_VIA="bash bench/gpu-run.sh dry-run $budget" WARPVOL_CAMPAIGN_ARGS=--tiny OUT="$tmp/out" bash bench/gpu-run.sh campaign "$budget") || status=$?
    rm -rf results/campaign-dry-run && mkdir -p results/campaign-dry-run
    cp -r "$tmp/out/campaign/." results/campaign-dry-run/
    rm -rf "$tmp"
    echo "dry run: exit $status; results/campaign-dry-run/summary.md"
    exit $status
    ;;
*)
    sed -n '2,24p' "$0" >&2
    exit 2
    ;;
esac
