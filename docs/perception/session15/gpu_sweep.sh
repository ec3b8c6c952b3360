#!/bin/bash
# Session 15 GPU sweep driver (run 2), kept as the record of how the sweep ran (docs/perception.md 'Session 15').
# data/gpu_s15 held real copies (not links: the device tool carries no link targets) of the paper's Detection
# folder (Detection/) and of data/paper_det_holdout (holdout/, the weights/README.md split command with cp).
# Ran as: bash gpu_sweep.sh /tmp/s15 cuda 100 7. Run 1 was this script with its candidates (see the doc table),
# --threads 1 --workers 1, soups of a1-a2 and b1-b3, the four best by hold-out returned, MAXMIN 6.
set -u
OUTD=$1; DEV=$2; SCALE=$3; MAXMIN=$4
export PYTHONPATH=$PWD/src/cottonsim_perception/src PYTHONUNBUFFERED=1 OMP_NUM_THREADS=${OMP:-1}
G=data/gpu_s15; H=$G/holdout; P=$G/Detection; R=$OUTD/runs; mkdir -p $R $OUTD/eval $OUTD/top
SIM=src/cottonsim_perception/weights/boll_detector_sim.pt
T="python3 src/cottonsim_perception/scripts/train --task det --data $H --batch 8 --mosaic 0.5 --final-lr-fraction 0.05 --threads 2 --workers 2 --device $DEV --max-minutes $MAXMIN"
ep() { echo $(( $1 * SCALE / 100 > 0 ? $1 * SCALE / 100 : 1 )); }
run() { name=$1; shift; $T --out $R/$name "$@" > $OUTD/log_$name.txt 2>&1; echo "$name rc=$?" >> $OUTD/rc.txt; }
run b1 --init-weights $SIM --imgsz 800x608 --lr 5e-4 --warmup-iters 30 --epochs $(ep 30) --seed 0 &
run b2 --init-weights $SIM --imgsz 800x608 --lr 5e-4 --warmup-iters 30 --epochs $(ep 30) --seed 1 &
run b3 --init-weights $SIM --imgsz 800x608 --lr 5e-4 --warmup-iters 30 --epochs $(ep 30) --seed 2 &
run c1 --init-weights $SIM --imgsz 960x736 --lr 5e-4 --warmup-iters 30 --epochs $(ep 30) --seed 0 &
run c2 --init-weights $SIM --imgsz 960x736 --lr 5e-4 --warmup-iters 30 --epochs $(ep 30) --seed 1 &
wait
# weight soups of same-recipe seeds (uniform average of the EMA weights)
python3 - "$R" <<'PY'
import sys, torch
R = sys.argv[1]
def soup(names, out):
    cks = [torch.load(f"{R}/{n}/best.pt", weights_only=True) for n in names]
    avg = dict(cks[0]); sd = {}
    for k, v in cks[0]["state_dict"].items():
        sd[k] = (sum(c["state_dict"][k].double() for c in cks) / len(cks)).to(v.dtype) if v.is_floating_point() else v
    avg["state_dict"] = sd; avg["train"] = dict(avg["train"], soup_of=names)
    import os; os.makedirs(f"{R}/{out}", exist_ok=True); torch.save(avg, f"{R}/{out}/best.pt")
for names, out in ((["b1", "b2", "b3"], "soup_b"), (["c1", "c2"], "soup_c")):
    try:
        soup(names, out)
    except Exception as exc:
        print("soup", out, "failed:", exc)
PY
E="python3 src/cottonsim_perception/scripts/evaluate --task det"
mkdir -p $R/base_sim && cp $SIM $R/base_sim/best.pt
for d in $R/*/; do n=$(basename $d); [ -f $d/best.pt ] || continue
  ( $E --data $H --split valid --weights $d/best.pt --json $OUTD/eval/${n}_holdout.json > $OUTD/eval/${n}_holdout.txt 2>&1
    $E --data $P --split valid,test --weights $d/best.pt --json $OUTD/eval/${n}_paper.json > $OUTD/eval/${n}_paper.txt 2>&1 ) &
done; wait
python3 - "$OUTD" <<'PY' | tee $OUTD/summary.txt
import json, glob, os, sys, shutil
O = sys.argv[1]; rows = []
def all_row(path, split):
    d = json.load(open(path))["splits"][split]["box"]["rows"]
    r = [r for r in d if r["class"] == "all"][0]
    return r
for f in sorted(glob.glob(f"{O}/eval/*_holdout.json")):
    n = os.path.basename(f)[:-len("_holdout.json")]
    try:
        h = all_row(f, "valid"); pj = f"{O}/eval/{n}_paper.json"
        v, t, vt = (all_row(pj, s) for s in ("valid", "test", "valid+test"))
        rows.append((h["map50"], n, h["map50"], h["map50_95"], v["map50"], t["map50"], vt["map50"], vt["map50_95"]))
    except Exception as e:
        print(n, "error", e)
print("name holdout50 holdout50-95 | paper valid50 test50 v+t50 v+t50-95")
for r in sorted(rows, reverse=True):
    print(r[1], " ".join(f"{100*x:.1f}" for x in r[2:4]), "|", " ".join(f"{100*x:.1f}" for x in r[4:]))
keep = [r[1] for r in sorted(rows, reverse=True) if r[1] != "base_sim"][:4]
print("returned checkpoints:", keep)
for n in keep:
    shutil.copy(f"{O}/runs/{n}/best.pt", f"{O}/top/{n}.pt")
PY
tar czf $OUTD/top/eval_logs.tgz -C $OUTD eval summary.txt $(cd $OUTD && ls log_*.txt rc.txt)
