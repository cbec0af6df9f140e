#!/usr/bin/env bash
# Walks the training settings through the command line: every setting settings.json records is a flag of
# `train --help` (its name with dashes), given a value (a switch: the one it does not have by default, so a
# switch on by default is turned off by --no-<name>) it trains and is recorded under its name, and
# given a value just outside the interval its help line shows it is refused with a message naming the flag.
# Usage: tests/settings.sh path/to/evnerf
set -euo pipefail
EV=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$EV" simulate planes --out "$work/rec" --width 32 --height 24 > /dev/null 2>&1
"$EV" train "$work/rec" --out "$work/default" --iterations 1 --threads 1 --quiet > /dev/null 2>&1
"$EV" train --help > "$work/help.txt"
python3 - "$EV" "$work" <<'PY'
import json, re, subprocess, sys
ev, w = sys.argv[1:]
help_text = open(f"{w}/help.txt").read()
entry = json.load(open(f"{w}/default/settings.json"))["runs"][0]
names = [k for k in entry if k not in ("from_step", "processes")]
assert len(names) >= 20, names
checked = refused = 0
for name in names:
    flag = "--" + name.replace("_", "-")
    line = next((l for l in help_text.splitlines() if re.match(r"\s*" + re.escape(flag) + r"(\s|,|\{|$)", l)), None)
    assert line is not None, f"{flag} is not in train --help"
    value = entry[name]
    args = [ev, "train", f"{w}/rec", "--out", f"{w}/{name}", "--quiet"] + (["--threads", "1"] if name != "threads" else [])
    if name != "iterations":
        args += ["--iterations", "1"]
    if isinstance(value, bool):  # a switch turns on; one that is on by default, its --no- form turns off
        no = "--no-" + flag[2:]
        args += [flag] if not value else [no]
        want = not value
        assert value or no not in help_text, f"{flag} is off by default, yet train --help offers {no}"
        assert not value or no in line, f"{flag} is on by default, yet its help line offers no {no}: {line}"
    else:
        if name == "iterations":
            value = 1
        if value is None:  # unset: the variant's own (tv), or learned (the refractory period): give it one
            value = 1e-4 if name == "refractory" else 0.05
        if name == "threads":
            value = 1
        args += [flag, str(value)]
        want = value
    r = subprocess.run(args, capture_output=True, text=True)
    assert r.returncode == 0, (flag, r.stderr)
    got = json.load(open(f"{w}/{name}/settings.json"))["runs"][0][name]
    assert got == want or (name == "shards" and got == 1), (flag, got, want)
    checked += 1
    m = re.search(re.escape(flag) + r"\s+(INT|UINT|FLOAT):(>=-?[0-9.e+-]+|>-?[0-9.e+-]+|[\[(][^\])]*[\])])", line)
    if not m:
        continue
    rng = m.group(2)
    bad = None
    if rng.startswith(">="):
        bad = float(rng[2:]) - 1
    elif rng.startswith(">"):
        bad = float(rng[1:])
    elif rng[0] in "[(":
        hi = float(rng[1:-1].split(",")[1])
        bad = hi + 1 if rng.endswith("]") else hi
    if bad is None:
        continue
    text = str(int(bad)) if m.group(1) != "FLOAT" else repr(bad)
    r = subprocess.run([ev, "train", f"{w}/rec", "--out", f"{w}/bad", flag, text], capture_output=True, text=True)
    assert r.returncode == 2 and flag in r.stderr and "must be" in r.stderr, (flag, text, r.returncode, r.stderr)
    refused += 1
print(f"settings: {checked} flags trained and recorded, {refused} refused outside their interval")
assert refused >= 15, refused
PY
