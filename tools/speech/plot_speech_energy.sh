#!/bin/sh
# Draws docs/images/speech-energy-librivox.png (docs/input-formats.md, "Human speech"): one
# LibriVox sentence of human speech (Debian's pocketsphinx-testdata) aligned with its transcript by
# `lipsync align`, the signal's level (RMS over 10 ms windows every 5 ms, dBFS) above the inner-lip
# gap that lipsyncd's mesh simulates from the alignment (lip_gap_trace, 30 frames/s with key
# frames), with the /p b m/ intervals of the alignment shaded. Where the lips seal, the level
# should be low: a lip closure stops the sound. Needs gnuplot (Debian: gnuplot-nox), python3 and a
# build with tests (lipsync, lip_gap_trace).
#   tools/speech/plot_speech_energy.sh [build dir] [output png]
set -eu

root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-"$root/build"}
out=${2:-"$root/docs/images/speech-energy-librivox.png"}
wav=/usr/share/pocketsphinx/test/data/librivox/sense_and_sensibility_01_austen_64kb-0930.wav
text="he might even have been made amiable himself"
command -v gnuplot >/dev/null || { echo "plot_speech_energy: gnuplot is missing (apt-get install gnuplot-nox)" >&2; exit 1; }
[ -r "$wav" ] || { echo "plot_speech_energy: $wav is missing (apt-get install pocketsphinx-testdata)" >&2; exit 1; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT INT TERM
"$build/clients/cli/lipsync" align "$wav" --text "$text" -o "$work/speech.TextGrid"
"$build/tests/face/lip_gap_trace" "$work/speech.TextGrid" arpabet > "$work/trace.tsv"
python3 - "$wav" "$work/speech.TextGrid" "$work/level.tsv" "$work/bilabials.tsv" <<'PY'
import math, re, struct, sys, wave
wav, grid, level_out, bilabial_out = sys.argv[1:]
with wave.open(wav) as w:
    rate = w.getframerate()
    samples = struct.unpack("<%dh" % w.getnframes(), w.readframes(w.getnframes()))
window, hop = rate // 100, rate // 200
with open(level_out, "w") as out:
    for start in range(0, len(samples) - window, hop):
        energy = sum(s * s for s in samples[start:start + window]) / window
        db = 10 * math.log10(energy / 32768.0 ** 2) if energy > 0 else -100
        out.write(f"{(start + window / 2) / rate:.4f}\t{max(db, -80):.2f}\n")
# The phones tier is the last tier: xmin, xmax, text triples.
text = open(grid).read()
phones = text[text.rfind('name = "phones"'):]
with open(bilabial_out, "w") as out:
    for xmin, xmax, label in re.findall(r'xmin = ([\d.]+)\s+xmax = ([\d.]+)\s+text = "([^"]*)"', phones):
        if label in ("P", "B", "M"):
            out.write(f"{xmin}\t{xmax}\t{label}\n")
PY

gnuplot <<PLOT
set terminal pngcairo size 1200,640 font "DejaVu Sans,11"
set output "$out"
set multiplot layout 2,1 title "\"He might even have been made amiable himself.\" (LibriVox, human speech; aligned with its transcript)"
set datafile separator "\t"
set grid
set xrange [0:3.3]
set style rect fc rgb "#f5b7b1" fs solid 0.5 noborder
set key top right
set ylabel "level (dBFS)"
set yrange [-80:0]
set format x ""
plot "$work/bilabials.tsv" using (\$1):(-80):(\$1):(\$2):(-80):(0) with boxxyerror fc rgb "#f5b7b1" fs solid 0.5 noborder title "/p b m/ (aligned, refined)", \
     "$work/level.tsv" using 1:2 with lines lw 1.5 lc rgb "#2c3e50" title "signal level, 10 ms RMS"
set format x "%g"
set xlabel "time (s)"
set ylabel "inner-lip gap (mm)"
set yrange [-0.5:32]
set key top left
plot "$work/bilabials.tsv" using (\$1):(-0.5):(\$1):(\$2):(-0.5):(32) with boxxyerror fc rgb "#f5b7b1" fs solid 0.5 noborder notitle, \
     "$work/trace.tsv" every ::1 using 1:4 with lines lw 2 lc rgb "#c0392b" title "rendered lip gap (physics mesh, 30 frames/s with key frames)"
unset multiplot
PLOT
echo "plot_speech_energy: wrote $out"
