#!/usr/bin/env bash
# Regenerates the dataset seeds from the short scenario; PDCAL names the pdcal binary
# (default: the workspace's debug build).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
pdcal="${PDCAL:-$here/../../target/debug/pdcal}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
"$pdcal" simulate --scenario "$here/scenario-ron/short.ron" --seed 1 --out "$tmp/tle"
cp "$tmp/tle/dataset.ron" "$here/dataset-ron/tle.ron"
cp "$tmp/tle/telemetry.csv" "$here/telemetry-csv/tle.csv"
cp "$tmp/tle/truth.csv" "$here/truth-csv/truth.csv"
cp "$tmp/tle/truth.ron" "$here/fixed/truth.ron"
# The PositionColumns twin: truth.csv's r_x_km, r_y_km, r_z_km (columns 16-18, one row per
# telemetry row) appended to the telemetry.
sed '/^    orbit: Tle($/,/^    ),$/c\    orbit: PositionColumns,' "$tmp/tle/dataset.ron" \
    >"$here/dataset-ron/positions.ron"
cut -d, -f16-18 "$tmp/tle/truth.csv" | paste -d, "$tmp/tle/telemetry.csv" - \
    >"$here/telemetry-csv/positions.csv"
for variant in tle positions; do
    {
        cat "$here/dataset-ron/$variant.ron"
        printf '\0'
        cat "$here/telemetry-csv/$variant.csv"
    } >"$here/dataset-pair/$variant.bin"
done
# The import-map seeds: the maps of fixtures/import (made by `cargo xtask
# make-import-fixture`) and the first 40 rows of its export, which every input is read against.
mkdir -p "$here/import-map"
cp "$here/../../fixtures/import/map.ron" "$here/../../fixtures/import/map-positions.ron" \
    "$here/import-map/"
head -n 41 "$here/../../fixtures/import/export.csv" >"$here/fixed/export.csv"
