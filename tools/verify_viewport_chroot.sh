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
# checkout with it). Nothing in the repository is written.
#
# Environment: CHROOTS, MIRROR (default http://deb.debian.org/debian), SUITES (default "trixie sid"),
# CASES (default "EEVEE:COMPOSITOR EEVEE:PER_PIXEL CYCLES:COMPOSITOR CYCLES:PER_PIXEL CYCLES:IN_RENDER"; an
# entry ENGINE:MODE:FLAG adds --FLAG, e.g. CYCLES:COMPOSITOR:no-final-render), CASE_TIMEOUT (seconds per Blender
# run, default 2400).
#
# CHECK=panel runs tools/verify_panel.py instead (the Atmosphere panel at the Properties editor's default width,
# issue 29): for each suite and each screen width in PANEL_WIDTHS (default "1920 1280": Blender's factory layout
# gives its Properties editor 339 and 225 px there), screenshots and the cut-text check into
# OUT_DIR/panel_<version>_<width>/, e.g. `sudo CHECK=panel SUITES=sid tools/verify_viewport_chroot.sh`.

set -euo pipefail

REPO=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-/work/viewport_out}
CHROOTS=${CHROOTS:-/work/chroots}
MIRROR=${MIRROR:-http://deb.debian.org/debian}
SUITES=${SUITES:-trixie sid}
CASES=${CASES:-EEVEE:COMPOSITOR EEVEE:PER_PIXEL CYCLES:COMPOSITOR CYCLES:PER_PIXEL CYCLES:IN_RENDER}
CASE_TIMEOUT=${CASE_TIMEOUT:-2400}
CHECK=${CHECK:-viewport}
PANEL_WIDTHS=${PANEL_WIDTHS:-1920 1280}
# python3-cattr and python3-requests: Blender 5.2's bundled extensions add-on imports them at startup.
PACKAGES="blender xvfb xauth mesa-utils x11-apps imagemagick python3-numpy libgl1-mesa-dri python3-cattr
python3-requests"
# sid's Release file can be older than its Valid-Until when the mirror is a snapshot: do not refuse it.
APT="apt-get -o Acquire::Check-Valid-Until=false"

mkdir -p "$OUT" "$CHROOTS"
MOUNTED=()
unmount_all() {   # the mounts made here, innermost (last made) first
    local index
    for ((index = ${#MOUNTED[@]} - 1; index >= 0; index--)); do
        umount "${MOUNTED[index]}" || echo "could not unmount ${MOUNTED[index]}" >&2
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

run_panel() {   # run_panel SUITE WIDTH: the panel check on a screen WIDTH px wide (tall enough for the whole tab)
    local suite=$1 width=$2 root=$CHROOTS/$1 version out
    version=$(chroot "$root" blender --version | awk 'NR == 1 {print $2}')
    out="$OUT/panel_${version}_${width}"
    mkdir -p "$out"
    echo "== panel, Blender $version, screen ${width} px wide"
    timeout "$CASE_TIMEOUT" chroot "$root" sh -c "cd '$REPO' && xvfb-run -a -s '-screen 0 ${width}x2400x24' \
        blender --factory-startup --python tools/verify_panel.py -- --out '$out'" > "$out/panel.log" 2>&1 \
        || echo "   exit status $? (see $out/panel.log)"
    grep '^PANEL' "$out/panel.log" | sed 's/^/   /' || true
}

for suite in $SUITES; do
    setup_chroot "$suite"
done
if [ "$CHECK" = panel ]; then
    for suite in $SUITES; do
        for width in $PANEL_WIDTHS; do
            run_panel "$suite" "$width"
        done
    done
    exit 0
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
