#!/usr/bin/env bash
# Renders a dvlcal HTML report (the DVL calibration's or the camera calibration's) in headless
# Chromium and fails when the browser reports any console message (SVG attribute errors, script
# errors) or when a section or plot is missing. In the DVL calibration's report it also reads the
# "what to do next" box from the rendered DOM: a list with at least one step, or the sentence
# that nothing is to be done; it prints the first step.
#
# usage: scripts/check_report.sh REPORT.html [SCREENSHOT.png]
#
# The browser is $CHROMIUM, else `chromium` (Debian), else `chromium-browser`. Exit status 0 when
# the report is fine, 1 when a check fails, 2 on usage errors or when no browser is found.
set -euo pipefail
trap 'echo "FAIL: $0 stopped at line $LINENO" >&2' ERR

PLOTS="residual-time-x residual-time-y residual-time-z velocity-before-x velocity-after-x
velocity-before-y velocity-after-y velocity-before-z velocity-after-z residuals-x residuals-y residuals-z
angular-velocity lever-arm offset-global offset-coarse offset-fine cost frames-tags frames-rms
reprojection-map-cam0 reprojection-time-cam0 reprojection-map-cam1 reprojection-time-cam1
pose-residual-pos pose-residual-rot trajectory"
SECTIONS="summary next-steps results correlation warnings residual-time velocity residuals motion
clock-offset refinement frames reprojection trajectory-fit dvl-log result-file"
# The DVL calibration's report has the "what to do next" box (src/report/guidance.rs).
steps_box=1

if [[ $# -lt 1 || $# -gt 2 ]]; then
    echo "usage: $0 REPORT.html [SCREENSHOT.png]" >&2
    exit 2
fi
report=$1
shot=${2:-}
if [[ ! -f $report ]]; then
    echo "$report: no such file" >&2
    exit 2
fi
# The camera calibration report (`<body data-report="camcal">`) has its own sections and plots;
# these lists match CAMCAL_SECTION_IDS, CAMCAL_PLOT_IDS and CAMCAL_CAMERA_PLOT_IDS in
# src/report/cameras.rs. A camera with any of its plots must have all three.
if grep -q '<body data-report="camcal"' "$report"; then
    SECTIONS="summary warnings results residuals coverage frames camchain"
    steps_box=0
    PLOTS="frame-rms"
    cams=$({ grep -o 'id="[a-z-]*-cam[0-9]*"' "$report" || true; } |
        sed 's/.*-cam\([0-9]*\)"/\1/' | sort -un)
    for c in $cams; do
        PLOTS+=" residual-hist-cam$c residual-map-cam$c coverage-grid-cam$c"
    done
fi
# The report of a calibration that stopped with an error (`<body data-report="failure">`); these
# lists match FAILURE_SECTION_IDS and FAILURE_PLOT_IDS in src/report/failure.rs.
if grep -q '<body data-report="failure"' "$report"; then
    SECTIONS="failure inputs counts time-spans detection dvl-log"
    steps_box=0
    PLOTS="time-spans"
fi
browser=${CHROMIUM:-}
if [[ -z $browser ]]; then
    for b in chromium chromium-browser; do
        if command -v "$b" >/dev/null 2>&1; then
            browser=$b
            break
        fi
    done
fi
if [[ -z $browser ]] || ! command -v "$browser" >/dev/null 2>&1; then
    echo "no Chromium found${browser:+ at '$browser'} (install Debian's chromium, or set CHROMIUM)" >&2
    exit 2
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# file:// URL of the report, percent-encoded (names may hold spaces, '#', '%', '<', '&' ...).
urlencode() {
    local s=$1 out="" c i
    local LC_ALL=C
    for ((i = 0; i < ${#s}; i++)); do
        c=${s:i:1}
        case $c in
        [A-Za-z0-9/._~-]) out+=$c ;;
        *) out+=$(printf '%%%02X' "'$c") ;;
        esac
    done
    printf '%s' "$out"
}
url="file://$(urlencode "$(cd "$(dirname "$report")" && pwd)/$(basename "$report")")"
# A private profile so that parallel runs do not share (and lock) one.
flags=(--headless --disable-gpu --no-sandbox --no-first-run --hide-scrollbars
    --user-data-dir="$work/profile" --enable-logging=stderr --v=0)

fail=0
problem() {
    echo "FAIL: $*" >&2
    fail=1
}

if ! timeout 120 "$browser" "${flags[@]}" --dump-dom "$url" >"$work/dom.html" 2>"$work/log.txt"; then
    echo "FAIL: the browser failed to render $report:" >&2
    tail -n 20 "$work/log.txt" >&2 || true
    exit 1
fi
# Console messages are what the page itself caused (malformed SVG attributes, scripts); the
# rest of the log is the browser talking about its sandbox, D-Bus and GPU.
if grep -q ':CONSOLE' "$work/log.txt"; then
    problem "console messages while rendering:"
    grep ':CONSOLE' "$work/log.txt" | head -n 20 >&2
fi

dom="$work/dom.html"
if ! grep -q '</html>' "$dom"; then
    problem "no document came back from the browser"
fi
for id in $SECTIONS; do
    grep -q "<section id=\"$id\"" "$dom" || problem "section '$id' missing"
done
for id in $PLOTS; do
    grep -q "<svg id=\"$id\"" "$dom" || problem "plot '$id' missing"
done
count() { grep -o "$1" "$dom" | wc -l || true; }
n_open=$(count '<svg')
n_close=$(count '</svg>')
n_sections=$(count '<section')
n_sections_closed=$(count '</section>')
[[ $n_open -eq $n_close ]] || problem "$n_open <svg> elements but $n_close closing tags"
[[ $n_sections -eq $n_sections_closed ]] ||
    problem "$n_sections sections but $n_sections_closed closing tags"
# Self-contained: nothing fetched, nothing executed.
if grep -Eiq '<script|<link|<iframe|<img|src=|href="(https?:|//)|url\((https?:|//)' "$report"; then
    problem "the report refers to scripts or external resources"
fi
# The box: its first step's text (tags dropped), or the sentence that nothing is to be done.
steps_words=""
if [[ $steps_box -eq 1 ]]; then
    first=$({ tr '\n' ' ' <"$dom" | grep -o '<ol id="next-steps-list">.*' || true; } |
        { grep -o '<li data-step="[A-Za-z]*"><strong>[^<]*</strong>' || true; } | sed -n 1p |
        sed -e 's/<[^>]*>//g' -e 's/&amp;/\&/g' -e 's/&lt;/</g' -e 's/&gt;/>/g')
    if [[ -n $first ]]; then
        steps_words="; first step: $first"
    elif grep -q '<p id="nothing-to-do">' "$dom"; then
        steps_words="; next steps: none"
    else
        problem "the next-steps box holds neither a step nor the sentence that nothing is to do"
    fi
fi
empty=$({ grep -o '<svg id="[^"]*"[^>]*data-empty="true"' "$dom" || true; } |
    sed 's/<svg id="\([^"]*\)".*/\1/' | paste -sd' ' -)

if [[ -n $shot ]]; then
    if ! timeout 120 "$browser" "${flags[@]}" --window-size=1000,12000 --screenshot="$shot" \
        "$url" >/dev/null 2>"$work/shot.txt" || [[ ! -s $shot ]]; then
        problem "no screenshot written to $shot"
    fi
fi

if [[ $fail -ne 0 ]]; then
    exit 1
fi
echo "ok: $report renders without console messages; $n_open plots, $n_sections sections" \
    "(without data: ${empty:-none})$steps_words"
