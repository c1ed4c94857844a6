#!/usr/bin/env bash
# Seeds corpus/<target>/ with the repository's own files (robots/, docs examples) and, when
# the Python package example-robot-data is installed, a dozen of its smaller URDFs.
set -euo pipefail
cd "$(dirname "$0")"
repo=..
corpus=corpus
mkdir -p "$corpus"/{urdf,measurements_csv,joints_csv,mcpc_table,stiffness,params,plan,stl,obj,collada,registration,export}
cp "$repo"/robots/*/*.urdf "$corpus/urdf/"
prefix=$(python3 -c 'import sys; print(sys.prefix)' 2>/dev/null || true)
root=$( [ -n "$prefix" ] && find "$prefix" -path '*/share/example-robot-data/robots' -type d 2>/dev/null | head -1 || true)
if [ -n "$root" ]; then
  find "$root" -name '*.urdf' -size -60k | sort | head -12 | while read -r f; do
    cp "$f" "$corpus/urdf/erd_$(basename "$f")"
  done
fi
# The first byte of a measurement input picks the units: 0 = m and rad, 3 = mm and deg.
{ printf '\x03'; head -12 "$repo/robots/robonaut/example/measurements.csv"; } > "$corpus/measurements_csv/example_mm_deg"
{ printf '\x00'; printf 'id,stage,tool,torso_joint1,torso_joint2,left_joint1,left_joint2,left_joint3,left_joint4,left_joint5,left_joint6,x,y,z,qw,qx,qy,qz\n1,arms,left_tool,0,0,0.1,0.2,0.3,0.4,0.5,0.6,0.5,0.3,1.1,1,0,0,0\n'; } > "$corpus/measurements_csv/pose_si"
printf 'stage,tool,torso_joint1,torso_joint2,left_joint1,right_joint1\r\ntorso,left_tool,0.1,0.2,0.3,0.4\r\narms,,1,2,3,4\r\n' > "$corpus/joints_csv/poses_crlf"
cp "$repo"/robots/robonaut/table*.yaml "$corpus/mcpc_table/"
cp "$repo"/robots/robonaut/stiffness.yaml "$corpus/stiffness/"
printf 'parameters:\n  - name: left_joint1 alpha\n    calibrated: 1.5712\n  - name: left_tool z\n    calibrated: 0.1451\n' > "$corpus/params/p1.yaml"
printf 'stages:\n  - name: torso\n    parameters: coupled\n    measurements: torso\n  - name: arms\n    parameters: arms\n    measurements: arms\n' > "$corpus/plan/p1.yaml"
# Meshes: the test cube, and the smaller STL/OBJ/COLLADA meshes of example-robot-data.
cp "$repo"/tests/data/cube.dae "$corpus/collada/"
printf 'solid cube\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid cube\n' > "$corpus/stl/ascii.stl"
printf 'mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n' > "$corpus/obj/tri.obj"
if [ -n "$root" ]; then
  for ext in stl obj dae; do
    target=$ext; [ "$ext" = dae ] && target=collada
    find "$root" -iname "*.$ext" -size -40k | sort | head -12 | while read -r f; do
      cp "$f" "$corpus/$target/erd_$(basename "$f")"
    done || true
  done
fi
printf 'units: {length: mm, angle: deg}\nxyz: [2300.0, -150.0, 420.0]\nrpy: [0.0, 0.0, 90.0]\n' > "$corpus/registration/r1.yaml"
printf 'units: {length: m, angle: rad}\nxyz: [1, 2, 3]\nrpy: [0.1, 0.2, 0.3]  # comment\n' > "$corpus/registration/r2.yaml"
cp "$corpus/params/p1.yaml" "$corpus/export/p1.yaml"
# The examples of docs/file-formats.md, sorted by their first line.
python3 - "$repo/docs/file-formats.md" "$corpus" <<'PY'
import re, sys
doc, corpus = open(sys.argv[1]).read(), sys.argv[2]
for n, (lang, body) in enumerate(re.findall(r"```(\w*)\n(.*?)```", doc, re.S)):
    lines = [l for l in body.split("\n") if l and not l.startswith("#")]
    if not lines:
        continue
    if lang == "text" and "," in lines[0]:
        columns = [c.strip() for c in lines[0].split(",")]
        if "tool" in columns and ("x" in columns or "ax" in columns):
            open(f"{corpus}/measurements_csv/doc{n}", "w").write("\x00" + body)
            open(f"{corpus}/measurements_csv/doc{n}_mm", "w").write("\x03" + body)
        else:
            open(f"{corpus}/joints_csv/doc{n}", "w").write(body)
    elif lang == "yaml":
        kind = ("plan" if "stages:" in body else "params" if "parameters:" in body
                else "mcpc_table" if "branches:" in body else "stiffness" if "payloads" in body else None)
        if kind:
            open(f"{corpus}/{kind}/doc{n}.yaml", "w").write(body)
PY
echo "seeded: $(find "$corpus" -type f | wc -l) files"
