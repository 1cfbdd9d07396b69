#!/bin/sh
# Draws docs/images/lip-gap-festival.png (docs/face.md, "Closures on real speech"): the inner-lip
# gap and the lower lip's distance to the upper teeth over one real sentence (Festival, from
# tests/data/closures), frame by frame as lipsyncd's mesh stream simulates it, with the closure key
# frames marked. Needs gnuplot (Debian: gnuplot-nox) and a build with tests (lip_gap_trace).
#   tools/face/plot_lip_gap.sh [path/to/lip_gap_trace] [input file] [output png]
set -eu

root=$(cd "$(dirname "$0")/../.." && pwd)
trace=${1:-"$root/build/tests/face/lip_gap_trace"}
input=${2:-"$root/tests/data/closures/festival_2.lab"}
out=${3:-"$root/docs/images/lip-gap-festival.png"}
command -v gnuplot >/dev/null || { echo "plot_lip_gap: gnuplot is missing (apt-get install gnuplot-nox)" >&2; exit 1; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT INT TERM
"$trace" "$input" > "$work/trace.tsv"
# Key frames of bilabial and labiodental closures, with their phoneme, for the markers.
awk -F'\t' 'NR > 1 && ($2 == "closure_start" || $2 == "closure_end") && ($3 ~ /^(pcl|bcl|m)$/)' "$work/trace.tsv" > "$work/bilabial.tsv"
awk -F'\t' 'NR > 1 && ($2 == "closure_start" || $2 == "closure_end") && ($3 ~ /^(f|v)$/)' "$work/trace.tsv" > "$work/labiodental.tsv"

gnuplot <<PLOT
set terminal pngcairo size 1200,520 font "DejaVu Sans,11"
set output "$out"
set title "\"Bob's mom found a very fine bamboo fence in Memphis.\" (Festival, 30 frames/s with key frames, face level 1)"
set xlabel "time (s)"
set ylabel "distance (mm)"
set yrange [-0.5:30]
set grid
set key top right
set datafile separator "\t"
plot "$work/trace.tsv" every ::1 using 1:4 with lines lw 2 lc rgb "#c0392b" title "inner-lip gap (middle 20 mm)", \
     "$work/trace.tsv" every ::1 using 1:5 with lines lw 1 dt 2 lc rgb "#2471a3" title "lower lip to upper teeth", \
     "$work/bilabial.tsv" using 1:4 with points pt 7 ps 1.3 lc rgb "#000000" title "/p b m/ key frames (must be ≤ 0.5 mm)", \
     "$work/labiodental.tsv" using 1:5 with points pt 5 ps 1.3 lc rgb "#1e8449" title "/f v/ key frames (must be ≤ 1 mm to the teeth)"
PLOT
echo "plot_lip_gap: wrote $out"
