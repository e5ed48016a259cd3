"""Compare two JSONL logs of benchmarks/diagnosis.py run by run: the same keys, outcomes,
findings and finding parameters (usage: python benchmarks/compare_sweeps.py A.jsonl B.jsonl)."""
import json
import sys


def load(p):
    d = {}
    for line in open(p):
        try: r = json.loads(line)
        except Exception: continue
        if "key" in r: d[r["key"]] = r
    return d
a, b = load(sys.argv[1]), load(sys.argv[2])
print("runs", len(a), len(b), "same keys", set(a) == set(b))
diff = []
for k in sorted(a):
    ra, rb = a[k], b.get(k, {})
    fa = [(f.get("effect"), json.dumps(f.get("parameters"), sort_keys=True)) for f in ra.get("found", [])]
    fb = [(f.get("effect"), json.dumps(f.get("parameters"), sort_keys=True)) for f in rb.get("found", [])]
    if ra.get("outcome") != rb.get("outcome") or fa != fb:
        diff.append(k)
print("records with different outcome or findings:", len(diff), diff[:5])
# parameters numerically equal?
maxrel = 0.0
for k in a:
    for fa, fb in zip(a[k].get("found", []), b.get(k, {}).get("found", [])):
        for key, va in (fa.get("parameters") or {}).items():
            vb = fb["parameters"].get(key)
            if isinstance(va, (int, float)) and isinstance(vb, (int, float)) and va:
                maxrel = max(maxrel, abs(va - vb) / abs(va))
print("largest relative difference of a finding's parameter:", maxrel)
