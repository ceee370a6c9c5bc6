#!/bin/sh
# Writes the seed corpora of the fuzz targets from ../shared (fuzz/README.md).
# Each seed is a file's first bytes behind the targets' option byte.
set -eu
S=${SHARED:-$(dirname "$0")/../../shared}
C=$(dirname "$0")/corpus
mkdir -p "$C/g2o_reader" "$C/fs_log" "$C/track" "$C/map" "$C/fs_config"
seed() { # target, option byte (octal), file, bytes
    out="$C/$1/seed_$(basename "$3")_$2"
    { printf "\\$2"; head -c "$4" "$3"; } > "$out"
}
for f in "$S"/datasets/parser/* "$S"/datasets/2d/* "$S"/datasets/3d/* "$S"/datasets/landmarks/*; do
    [ -f "$f" ] && seed g2o_reader 000 "$f" 3000
done
for f in "$S"/datasets/parser/*; do seed g2o_reader 001 "$f" 3000; done
for f in "$S"/reliability/*.jsonl; do seed fs_log 000 "$f" 6000; seed fs_log 001 "$f" 6000; done
for f in "$S"/tracks/*.csv "$S"/tracks/*.yaml "$S"/reliability/fssim_*; do
    case "$f" in *.yaml) y=1 ;; *) y=0 ;; esac
    case "$f" in *acceleration*) k=2 ;; *skidpad*) k=4 ;; *) k=0 ;; esac
    seed track "00$((y + k))" "$f" 8000
    head -c 8000 "$f" > "$C/map/seed_$(basename "$f")"
done
for f in "$(dirname "$0")"/../configs/*.toml; do cp "$f" "$C/fs_config/seed_$(basename "$f")"; done
