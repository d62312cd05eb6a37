#!/bin/bash
# SPDX-License-Identifier: GPL-3.0-or-later
#
# Verify what a real GUI Blender's viewport shows with Atmos on, in Debian's Blender 4.3 (trixie) and 5.2 (sid).
#
#   sudo tools/verify_viewport_chroot.sh [OUT_DIR]          # default OUT_DIR: /work/viewport_out
#
# Needs root, debootstrap and network access to a Debian mirror; no GPU (Mesa's llvmpipe under Xvfb gives
# Blender its OpenGL 4.5). It makes each chroot under $CHROOTS (default /work/chroots) once if missing, bind-mounts
# /proc, /sys, /dev, the repository and OUT_DIR at the same paths inside, installs Blender and Xvfb there, runs
# tools/verify_viewport.py in a GUI Blender for every case (engine x Atmos mode; In-Render only where Blender
# is 4.5+) and prints a table from the JSON files the script writes. Screenshots: OUT_DIR/<tag>_<phase>.png.
# The bind mounts it made are undone on exit (a chroot removed while the repository is mounted in it would take the
# checkout with it). The viewport check writes nothing in the repository.
#
# Environment: CHROOTS, MIRROR (default http://deb.debian.org/debian), SUITES (default "trixie sid"),
# CASES (default "EEVEE:COMPOSITOR EEVEE:PER_PIXEL CYCLES:COMPOSITOR CYCLES:PER_PIXEL CYCLES:IN_RENDER"; an
# entry ENGINE:MODE:FLAG adds --FLAG, e.g. CYCLES:COMPOSITOR:no-final-render), CASE_TIMEOUT (seconds per Blender
# run, default 2400).
#
# CHECK=panel checks the extension as an artist installs it, from a clean clone in one command:
#
#   sudo CHECK=panel tools/verify_viewport_chroot.sh          # default OUT_DIR: docs/panel, SUITES: sid
#
# In each suite's Blender it builds the zip from this checkout (`blender --command extension build`, into
# OUT_DIR/dist), installs it into a fresh HOME (`blender --command extension install-file -e`), runs
# `blender -b --command atmos render valley ...` and a `blender -b --python-expr` script through the installed
# package and requires exit status 0 from both, then runs tools/verify_panel.py --zip in a GUI Blender: for each
# screen width in PANEL_WIDTHS (default "1920": Blender's factory layout gives its Properties editor 339 px there;
# 1280 gives 225 px) screenshots and the cut-text check (panel.json) into OUT_DIR/<version>_<width>/. Logs go to
# LOGS (default /tmp/atmos_panel_logs). The script's exit status is 1 when any of these failed. Debian trixie's Blender (4.3) is older than the extension's minimum, 4.5.

set -euo pipefail

REPO=$(cd "$(dirname "$0")/.." && pwd)
CHECK=${CHECK:-viewport}
if [ "$CHECK" = panel ]; then
    OUT=${1:-$REPO/docs/panel}
    SUITES=${SUITES:-sid}
else
    OUT=${1:-/work/viewport_out}
    SUITES=${SUITES:-trixie sid}
fi
OUT=$(mkdir -p "$OUT" && cd "$OUT" && pwd)
CHROOTS=${CHROOTS:-/work/chroots}
MIRROR=${MIRROR:-http://deb.debian.org/debian}
CASES=${CASES:-EEVEE:COMPOSITOR EEVEE:PER_PIXEL CYCLES:COMPOSITOR CYCLES:PER_PIXEL CYCLES:IN_RENDER}
CASE_TIMEOUT=${CASE_TIMEOUT:-2400}
PANEL_WIDTHS=${PANEL_WIDTHS:-1920}
LOGS=${LOGS:-/tmp/atmos_panel_logs}
FAILED=0
# python3-cattr and python3-requests: Blender 5.2's bundled extensions add-on imports them at startup.
PACKAGES="blender xvfb xauth mesa-utils x11-apps imagemagick python3-numpy libgl1-mesa-dri python3-cattr
python3-requests"
# sid's Release file can be older than its Valid-Until when the mirror is a snapshot: do not refuse it.
APT="apt-get -o Acquire::Check-Valid-Until=false"

mkdir -p "$OUT" "$CHROOTS"
MOUNTED=()
unmount_all() {   # the mounts made here, innermost (last made) first; a mount still busy for a moment is retried
    local index try
    for ((index = ${#MOUNTED[@]} - 1; index >= 0; index--)); do
        for try in 1 2 3 4 5 6 7 8 9 10; do
            umount "${MOUNTED[index]}" 2>/dev/null && break
            [ "$try" = 10 ] && echo "could not unmount ${MOUNTED[index]}" >&2
            sleep 1
        done
    done
}
trap unmount_all EXIT

bind() {   # bind SOURCE TARGET: bind-mount unless TARGET is a mount point already
    mountpoint -q "$2" || { mount --bind "$1" "$2" && MOUNTED+=("$2"); }
}

setup_chroot() {   # setup_chroot SUITE: debootstrap (once), mounts, packages (once)
    local suite=$1 root=$CHROOTS/$1
    if [ ! -x "$root/usr/bin/apt-get" ]; then
        command -v debootstrap >/dev/null || { apt-get update -q && apt-get install -y -q debootstrap; }
        debootstrap --variant=minbase "$suite" "$root" "$MIRROR"
    fi
    for dir in proc sys dev dev/pts; do
        bind "/$dir" "$root/$dir"
    done
    for dir in "$REPO" "$OUT"; do
        mkdir -p "$root$dir"
        bind "$dir" "$root$dir"
    done
    cp /etc/resolv.conf "$root/etc/resolv.conf"
    if ! chroot "$root" sh -c 'command -v blender && command -v xvfb-run && command -v import' >/dev/null; then
        # shellcheck disable=SC2086  (the package list is split on purpose)
        chroot "$root" env DEBIAN_FRONTEND=noninteractive sh -c \
            "$APT update -q && $APT install -y -q --no-install-recommends $(echo $PACKAGES)"
    fi
    chroot "$root" blender --version | awk 'NR == 1'   # awk reads it all: no SIGPIPE under pipefail
    chroot "$root" blender -b --factory-startup --python-expr 'import numpy; print("numpy", numpy.__version__)' \
        2>&1 | grep '^numpy'
}

run_case() {   # run_case SUITE ENGINE MODE [FLAG]
    local suite=$1 engine=$2 mode=$3 flag=${4:-} root=$CHROOTS/$1 version tag
    version=$(chroot "$root" blender --version | awk 'NR == 1 {print $2}')
    if [ "$mode" = IN_RENDER ] && ! printf '%s\n4.5\n' "$version" | sort -V -C -r; then
        echo "skip: $engine $mode needs Blender 4.5+ (here $version)"
        return
    fi
    tag="${version}_$(echo "$engine" | tr 'A-Z' 'a-z')_$(echo "$mode" | tr 'A-Z' 'a-z')${flag:+_${flag//-/_}}"
    echo "== $tag"
    # A GUI Blender, not -b: the script drives the viewport from timers and quits Blender when done.
    timeout "$CASE_TIMEOUT" chroot "$root" sh -c "cd '$REPO' && xvfb-run -a -s '-screen 0 1280x800x24' \
        blender --factory-startup --python tools/verify_viewport.py -- --engine $engine --mode $mode \
        --out '$OUT' --tag $tag ${flag:+--$flag}" > "$OUT/$tag.log" 2>&1 || echo "   exit status $? (see $OUT/$tag.log)"
    grep '^VIEWPORT' "$OUT/$tag.log" | grep -v ' poll ' | sed 's/^/   /' || true
}

build_zip() {   # build_zip SUITE: the extension zip of this checkout, built by the suite's Blender; ZIP: its path there
    local root=$CHROOTS/$1
    rm -rf "$root/tmp/atmos_dist" && mkdir -p "$root/tmp/atmos_dist" "$LOGS"
    chroot "$root" blender --command extension build --source-dir "$REPO" --output-dir /tmp/atmos_dist \
        > "$LOGS/build.log" 2>&1 || { echo "zip build failed (see $LOGS/build.log)"; exit 1; }
    ZIP=$(cd "$root" && ls tmp/atmos_dist/atmos-*.zip) && ZIP=/$ZIP
}

in_home() {   # in_home SUITE COMMAND: COMMAND in the suite's chroot with HOME a fresh folder (no user settings)
    local root=$CHROOTS/$1
    chroot "$root" env HOME=/tmp/atmos_home sh -c "$2"
}

check_cli() {   # check_cli SUITE: install the zip, then the command line's exit status must be 0
    local suite=$1 root=$CHROOTS/$1 status
    rm -rf "$root/tmp/atmos_home" && mkdir -p "$root/tmp/atmos_home"
    echo "== installed extension, command line"
    in_home "$suite" "blender --command extension install-file -r user_default -e '$ZIP'" > "$LOGS/cli.log" 2>&1 \
        || { echo "   install: exit status $? (see $OUT/cli.log)"; FAILED=1; return; }
    status=0
    in_home "$suite" "cd /tmp/atmos_home && blender -b --command atmos render valley --preset sunset \
        --resolution 160x90 --samples 8 --output /tmp/atmos_home/valley.png" >> "$LOGS/cli.log" 2>&1 || status=$?
    [ -f "$root/tmp/atmos_home/valley.png" ] || status="${status}, no image"
    echo "   blender -b --command atmos render valley: exit status $status"
    [ "$status" = 0 ] || FAILED=1
    status=0
    in_home "$suite" "blender -b --python-expr 'import bpy
from bl_ext.user_default.atmos.atmos_addon import api
api.enable(bpy.context.scene, preset=\"overcast\")
print(\"ATMOS_PYTHON_OK\", api.is_enabled(bpy.context.scene))'" >> "$LOGS/cli.log" 2>&1 || status=$?
    grep -q '^ATMOS_PYTHON_OK True' "$LOGS/cli.log" || status="${status}, the script did not finish"
    echo "   blender -b --python-expr (api.enable through the installed package): exit status $status"
    [ "$status" = 0 ] || FAILED=1
}

run_panel() {   # run_panel SUITE WIDTH: the panel check on a screen WIDTH px wide (tall enough for the whole tab)
    local suite=$1 width=$2 root=$CHROOTS/$1 version out status=0
    version=$(chroot "$root" blender --version | awk 'NR == 1 {print $2}')
    out="$OUT/${version}_${width}"
    rm -rf "$out" && mkdir -p "$out"
    echo "== panel, Blender $version, screen ${width} px wide"
    rm -rf "$root/tmp/atmos_home" && mkdir -p "$root/tmp/atmos_home"
    timeout "$CASE_TIMEOUT" chroot "$root" env HOME=/tmp/atmos_home sh -c "cd '$REPO' && \
        xvfb-run -a -s '-screen 0 ${width}x2400x24' blender --factory-startup --python tools/verify_panel.py -- \
        --out '$out' --zip '$ZIP'" > "$LOGS/panel_${version}_${width}.log" 2>&1 || status=$?
    grep '^PANEL' "$LOGS/panel_${version}_${width}.log" | sed 's/^/   /' || true
    echo "   exit status $status (log: $LOGS/panel_${version}_${width}.log)"
    [ "$status" = 0 ] || FAILED=1
}

for suite in $SUITES; do
    setup_chroot "$suite"
done
if [ "$CHECK" = panel ]; then
    for suite in $SUITES; do
        build_zip "$suite"
        check_cli "$suite"
        for width in $PANEL_WIDTHS; do
            run_panel "$suite" "$width"
        done
    done
    echo "panel check: $([ "$FAILED" = 0 ] && echo passed || echo FAILED)"
    exit "$FAILED"
fi
for suite in $SUITES; do
    for case in $CASES; do
        IFS=: read -r engine mode flag <<< "$case"
        run_case "$suite" "$engine" "$mode" "$flag"
    done
done

# The results table, from the JSON files (any Python 3 with numpy; the first chroot has one).
first=$(echo "$SUITES" | awk '{print $1}')
chroot "$CHROOTS/$first" python3 "$REPO/tools/verify_viewport.py" --table "$OUT"
