#!/usr/bin/env bash
# Builds each user mistake of docs/accuracy.md ("The user's mistakes") from sample_data/stereo,
# calibrates it, and compares the result with the truth. Usage: scripts/mistakes.sh [WORKDIR]
# (BIN: the dvlcal binary, default target/release/dvlcal; run from the repository).
set -u
BIN=${BIN:-target/release/dvlcal}; S=${S:-sample_data/stereo}; W=${1:-/tmp/dvlcal-mistakes}
S=$(cd "$S" && pwd); BIN=$(cd "$(dirname "$BIN")" && pwd)/$(basename "$BIN")
rm -rf $W; mkdir -p $W
mk() { # name: a copy of the sample with symlinked images
  local d=$W/$1; mkdir -p $d/truth; ln -s $S/cam0 $d/cam0; ln -s $S/cam1 $d/cam1
  cp $S/camchain.yaml $S/target.yaml $S/dvl.jsonl $d/; cp $S/truth/calibration.yaml $d/truth/; echo $d; }
run() { local name=$1; shift; local d=$W/$name
  $BIN calibrate $d --out $d/out/calibration.yaml "$@" > $d/stdout.txt 2>&1; echo $? > $d/rc
  $BIN compare-calib --estimate $d/out/calibration.yaml --truth $d/truth/calibration.yaml > $d/cmp.txt 2>&1; }
d=$(mk clean); run clean
d=$(mk board97); sed -i 's/tag_size: 0.088/tag_size: 0.090722/' $d/target.yaml; run board97
d=$(mk board103); sed -i 's/tag_size: 0.088/tag_size: 0.085437/' $d/target.yaml; run board103
d=$(mk focal2); python3 - $d/camchain.yaml <<'P'
import sys,re
p=sys.argv[1]; s=open(p).read()
s=s.replace("intrinsics: [458.0, 457.0,","intrinsics: [467.16, 466.14,").replace("intrinsics: [457.5, 456.2,","intrinsics: [466.65, 465.324,")
open(p,'w').write(s)
P
run focal2
d=$(mk focal_cam1); python3 - $d/camchain.yaml <<'P'
import sys
p=sys.argv[1]; s=open(p).read()
s=s.replace("intrinsics: [457.5, 456.2,","intrinsics: [466.65, 465.324,")
open(p,'w').write(s)
P
run focal_cam1
d=$(mk dvl_small); run dvl_small --dvl-sigma 0.001
d=$(mk dvl_large); run dvl_large --dvl-sigma 0.1
d=$(mk fixed_mm); printf 'T_cam_dvl:\n  - [0.9981381401463493, -0.05031551179318922, -0.034476114313772156, 50]\n  - [0.03547577061103431, 0.019111553575554722, 0.9991877792584745, 250]\n  - [-0.04961575238510571, -0.9985504983689699, 0.020860952095763472, -100]\n  - [0.0, 0.0, 0.0, 1.0]\ntime_offset_s: 0.07\nvelocity_scale: 1.01\n' > $d/guess.yaml; run fixed_mm --method fixed --init $d/guess.yaml
dvlmod() { python3 - "$1" "$2" <<'P'
import json,sys
d,kind=sys.argv[1],sys.argv[2]
L=open(d+'/dvl.jsonl').read().splitlines()
vel=[i for i,l in enumerate(L) if '"type":"velocity"' in l.replace(' ','')]
t=[json.loads(L[i])['time_of_validity'] for i in vel]
mid=vel[len(vel)*3//5]; tm=t[len(t)//2]
out=[]
for i,l in enumerate(L):
    if i not in vel: out.append(l); continue
    v=json.loads(l)
    for k in ['time_of_validity','time_of_transmission']:
        if k not in v: continue
        if kind=='back' and i>=mid: v[k]-=10_000_000
        if kind=='forward' and i>=mid: v[k]+=10_000_000
        if kind=='restart' and i>=mid: v[k]=v[k]-t[vel.index(mid)]+5_000_000
        if kind=='drift': v[k]=int(v[k]+(v[k]-tm)*200e-6)
    out.append(json.dumps(v,separators=(',',':')))
open(d+'/dvl.jsonl','w').write('\n'.join(out)+'\n')
P
}
for k in back forward restart drift; do d=$(mk clock_$k); dvlmod $d $k; run clock_$k; done
d=$(mk clock_drift_est); dvlmod $d drift; run clock_drift_est --clock-drift
# One line per case: exit status and the comparison with the truth.
for d in "$W"/*/; do
  k=$(basename "$d")
  printf '%-14s rc=%s  %s\n' "$k" "$(cat "$d/rc")" "$(grep -h largest "$d/cmp.txt" 2>/dev/null)"
done
