#!/bin/sh
# Rebuild and rerun the ns-3 reference kept in ns3_highway_pdr.csv (Debian bookworm: apt-get install ns3 libns3-dev g++).
# 40 independent runs (RngRun 1..40) of v2v_pdr.cc: one sender, receivers every metre 1..999 m, 20 packets each.
set -e
cd "$(dirname "$0")"
g++ -O1 -std=c++17 v2v_pdr.cc -o /tmp/v2v_pdr $(ls /usr/lib/x86_64-linux-gnu/libns3*.so | sed 's|.*/lib\(ns3[^.]*\)\.so|-l\1|')
for r in $(seq 1 40); do /tmp/v2v_pdr --run=$r --packets=20 --maxDist=999; done | awk '
  { b = int($1 / 50); rx[b] += $2; n[b] += $3 }
  END { print "from_m,to_m,pdr,n"; for (i = 0; i < 20; i++) printf "%d,%d,%.4f,%d\n", i * 50, i * 50 + 50, rx[i] / n[i], n[i] }' > ns3_highway_pdr.csv
cat ns3_highway_pdr.csv
