#!/bin/bash
# Issue 26 acceptance (usage: bash benchmarks/cluster_check.sh;
# needs cdprid[cluster]): a 20-run diagnosis sweep, serial vs a 2-worker local cluster;
# then a 2-worker run killed half way and restarted
set -u
cd "$(dirname "$0")/.."
PY="${PYTHON:-.venv/bin/python}"
export PYTHONPATH=$PWD/src
OUT="${OUT:-$(mktemp -d)}"
ARGS="--robots four --kinds clean,pair --seeds 4 --quick"
t0=$(date +%s.%N); $PY benchmarks/diagnosis.py $ARGS --jsonl $OUT/serial.jsonl --out $OUT/serial.md > $OUT/serial.log 2>&1; rc=$?; t1=$(date +%s.%N)
echo "serial: rc $rc $(echo "$t1 - $t0" | bc) s"
t0=$(date +%s.%N); $PY benchmarks/diagnosis.py $ARGS --workers 2 --jsonl $OUT/cluster.jsonl --out $OUT/cluster.md > $OUT/cluster.log 2>&1; rc=$?; t1=$(date +%s.%N)
echo "cluster: rc $rc $(echo "$t1 - $t0" | bc) s"
# killed half way: SIGKILL the whole process group once 10 records are in the log
setsid $PY benchmarks/diagnosis.py $ARGS --workers 2 --jsonl $OUT/killed.jsonl --out $OUT/killed.md > $OUT/killed1.log 2>&1 &
pid=$!
while [ "$(grep -c key $OUT/killed.jsonl 2>/dev/null || echo 0)" -lt 10 ]; do sleep 1; done
kill -KILL -- -$pid; sleep 2
echo "killed with $(grep -c key $OUT/killed.jsonl) records in the log"
$PY benchmarks/diagnosis.py $ARGS --workers 2 --jsonl $OUT/killed.jsonl --out $OUT/killed.md > $OUT/killed2.log 2>&1
echo "restart: rc $? ; $(grep -m1 'sweep:' $OUT/killed2.log)"
$PY benchmarks/compare_sweeps.py $OUT/serial.jsonl $OUT/cluster.jsonl
$PY benchmarks/compare_sweeps.py $OUT/serial.jsonl $OUT/killed.jsonl
