"""Prints bench/mpi.sh's results: per preset, the step time of 2 processes x 1 thread (exchange auto and
dense) against 1 process x 2 threads with the same 2 shards per step (pair ratios, their median), the
exchange's bytes and seconds per step, and a model of N nodes built from these figures.

The model (weak scaling: every node computes one shard per step on its own cores, so a step of N nodes
is N shards): step(N) = compute + allreduce(bytes), with a ring allreduce taking
2 (N - 1) / N * bytes / bandwidth + 2 (N - 1) * latency. Dense sends every parameter (4 bytes each);
sparse sends a bitmap of 64-byte blocks (ORed first) and the blocks some node touched, whose share of the
table for N shards is 1 - (1 - f1)^N (shards drawn independently), f1 solved from the measured 2-shard
union. Efficiency is compute / step(N)."""
import json, statistics, sys

out, pairs = sys.argv[1], int(sys.argv[2])


def last(kind, preset, p):
    with open(f"{out}/{kind}_{preset}_{p}/log.jsonl") as f:
        rows = [json.loads(l) for l in f]
    r = rows[-1]
    return r, r["seconds"] / r["step"]


NETS = (("10 GbE", 1.25e9, 20e-6), ("100 Gb/s InfiniBand", 12.5e9, 2e-6))
for preset in ("fast", "paper"):
    a = [last("A", preset, p)[1] for p in range(1, pairs + 1)]
    b = [last("B", preset, p) for p in range(1, pairs + 1)]
    c = [last("C", preset, p) for p in range(1, pairs + 1)]
    rb = [x[1] / y for x, y in zip(b, a)]
    rc = [x[1] / y for x, y in zip(c, a)]
    print(f"== {preset}: {b[0][0]['step']} steps of 2 shards, seed 1, pairs {pairs}")
    print(f"  1 process x 2 threads: {statistics.median(a):.3f} s/step (median; range {min(a):.3f}-{max(a):.3f})")
    for name, runs, ratios in (("2 processes x 1 thread, auto", b, rb), ("2 processes x 1 thread, dense", c, rc)):
        s = [x[1] for x in runs]
        ex = [x[0]["exchange_seconds_per_step"] for x in runs]
        print(f"  {name}: {statistics.median(s):.3f} s/step; time ratio to 1 process {statistics.median(ratios):.3f}"
              f" (pairs {', '.join(f'{r:.3f}' for r in ratios)}); exchange {statistics.median(ex) * 1e3:.2f} ms/step,"
              f" {runs[0][0]['exchange_bytes_per_step'] / 1e6:.3f} MB/step, sparse steps in the last period"
              f" {runs[0][0]['sparse_steps']}, blocks touched {100 * runs[0][0]['touched_blocks']:.1f} %")
    dense = c[0][0]["exchange_bytes_per_step"]
    f2 = b[0][0]["touched_blocks"]
    f1 = 1 - (1 - min(f2, 0.999999)) ** 0.5
    compute = statistics.median(a) / 2  # one shard on one 2-core node
    print(f"  model: compute {compute * 1e3:.1f} ms per shard on a 2-core node; dense {dense / 1e6:.2f} MB; "
          f"one shard touches {100 * f1:.1f} % of the blocks")
    print("  | nodes | network | dense: step ms, efficiency | sparse: MB, step ms, efficiency |")
    print("  |---|---|---|---|")
    for n in (2, 4, 8, 16, 32, 64):
        for net, bw, lat in NETS:
            ring = lambda nbytes: 2 * (n - 1) / n * nbytes / bw + 2 * (n - 1) * lat
            fd = compute + ring(dense)
            fn = 1 - (1 - f1) ** n
            sparse_bytes = min(dense, fn * dense) + dense / 64 / 8
            fs = compute + ring(dense / 64 / 8) + ring(min(dense, fn * dense))
            print(f"  | {n} | {net} | {fd * 1e3:.1f}, {100 * compute / fd:.0f} % | {sparse_bytes / 1e6:.2f}, {fs * 1e3:.1f}, "
                  f"{100 * compute / fs:.0f} % |")
