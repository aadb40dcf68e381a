#!/usr/bin/env python3
"""Fuzzes `mps run` with mutated case files.

    tools/fuzz_cases.py MPS_BINARY [--count 10000] [--jobs 2] [--seed 1] [--keep DIR]

Seeds are the shipped examples made small (spacing x2, at most 20 steps, no VTU). Each case
gets 1-3 mutations: a number replaced by an extreme (0, -1, 1e308, 1e-300, nan, inf, huge
integers, a power-of-ten scale), a string, boolean or array changed, a line deleted or
duplicated, a key renamed, the text truncated or random bytes inserted. Each run gets 10 s;
a run still going then is killed and counts as a hang unless it wrote a line (start, progress or heartbeat).

Counted: exit codes (0 done, 1 bad input, 2 breakdown, 3 I/O), panics (101), signals,
hangs, and exit-1 messages that are not one line naming the case file. Failing cases are
copied to --keep (default fuzz_failures/) with the command. Exit status 1 if any defect.
"""
import argparse
import collections
import concurrent.futures as cf
import os
import random
import re
import shutil
import subprocess
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
CASES = os.path.join(HERE, "..", "crates", "mps", "cases")
EXTREMES = ["0", "-0.0", "-1", "1", "1e308", "-1e308", "1e-300", "nan", "inf", "-inf",
            "9223372036854775807", "18446744073709551615", "-9223372036854775808",
            "4294967296", "1e10", "1e-10", "2", "0.5", "100000", "3.0"]
STRINGS = ['""', '"water"', '"air"', '"x"', '"MPS-HS-GC-DS"', '"CMPS-HS"', '"amg-cg"',
           '"rectangle"', '"circle"', '"hydrostatic"', '"rotation"', '"expression"',
           '"x*y"', '"remove"', '"probe_reference"', '"front_reference"', '"1/0"', '"sqrt(-1)"', '"' + "a" * 300 + '"', '"\\u0000"', '"../x"']
NUMBER = re.compile(r"(?<![A-Za-z_\"])-?\d+(\.\d+)?([eE][-+]?\d+)?")


def seed_texts():
    out = []
    for name in sorted(os.listdir(CASES)):
        if not name.endswith(".toml"):
            continue
        text = open(os.path.join(CASES, name)).read()
        text = re.sub(r"^spacing = ([\d.eE-]+)",
                      lambda m: f"spacing = {float(m.group(1)) * 2}", text, flags=re.M)
        if re.search(r"^max_steps", text, flags=re.M):
            text = re.sub(r"^max_steps = \d+", "max_steps = 20", text, flags=re.M)
        else:
            text = re.sub(r"^\[time\]\n", "[time]\nmax_steps = 20\n", text, flags=re.M)
        if re.search(r"^vtu = ", text, flags=re.M):
            text = re.sub(r"^vtu = \w+", "vtu = false", text, flags=re.M)
        elif "[output]" in text:
            text = text.replace("[output]\n", "[output]\nvtu = false\n", 1)
        else:
            text += "\n[output]\nvtu = false\n"
        out.append((name, text))
    return out


def mutate(text, rng):
    kind = rng.choice(["number"] * 6 + ["string", "bool", "array", "delete", "duplicate",
                                        "rename", "truncate", "bytes", "table"])
    lines = text.split("\n")
    if kind == "number":
        spots = list(NUMBER.finditer(text))
        if spots:
            m = rng.choice(spots)
            if rng.random() < 0.3:
                v = float(m.group(0)) * 10 ** rng.randint(-12, 12)
                new = repr(v)
            else:
                new = rng.choice(EXTREMES)
            return text[:m.start()] + new + text[m.end():]
    if kind == "string":
        spots = list(re.finditer(r'"[^"\n]*"', text))
        if spots:
            m = rng.choice(spots)
            return text[:m.start()] + rng.choice(STRINGS) + text[m.end():]
    if kind == "bool":
        return text.replace(rng.choice(["true", "false"]), rng.choice(["false", "1", "\"yes\""]), 1)
    if kind == "array":
        spots = list(re.finditer(r"\[[^\[\]\n]*\]", text))
        if spots:
            m = rng.choice(spots)
            new = rng.choice(["[]", "[1.0]", "[0.0, 0.0, 0.0]", "[nan, nan]", "[1e308, -1e308]",
                              "[0.5, 0.5]", "[-1.0, 2.0]"])
            return text[:m.start()] + new + text[m.end():]
    if kind == "delete" and len(lines) > 1:
        del lines[rng.randrange(len(lines))]
        return "\n".join(lines)
    if kind == "duplicate" and lines:
        k = rng.randrange(len(lines))
        lines.insert(k, lines[k])
        return "\n".join(lines)
    if kind == "rename":
        spots = list(re.finditer(r"^(\w+) =", text, flags=re.M))
        if spots:
            m = rng.choice(spots)
            return text[:m.start(1)] + rng.choice(["shape", "kind", "nme", "z", "end"]) + text[m.end(1):]
    if kind == "truncate":
        return text[: rng.randrange(len(text) + 1)]
    if kind == "bytes":
        k = rng.randrange(len(text) + 1)
        junk = "".join(chr(rng.randrange(1, 0x3000)) for _ in range(rng.randint(1, 8)))
        return text[:k] + junk + text[k:]
    if kind == "table":
        block = rng.choice(["\n[[fluid]]\nphase = \"water\"\nshape = { type = \"circle\", center = [0.0, 0.0], radius = 1e9 }\n",
                            "\n[[walls]]\nshape = { type = \"rectangle\", min = [-1e308, 0.0], max = [1e308, 1.0] }\n",
                            "\n[[probes]]\nname = \"p\"\nposition = [nan, 0.0]\n",
                            "\n[constants]\nk = 1e308\n",
                            "\n[[phases]]\nname = \"water\"\ndensity = -1.0\nviscosity = 0.0\n"])
        return text + block
    return text


# Lines `mps run` prints on stderr while it sets up: the settled start's announcement and
# the heartbeat (`[5 s] still: ...`).
PROGRESS = re.compile(r"^(\S.*: relaxing the tank at rest for up to .* first \(.*\)|\[\d+ s\] still: .*)$")


def run_one(binary, work, k, name, text, timeout):
    case = os.path.join(work, f"case_{k}.toml")
    with open(case, "w", encoding="utf-8", errors="surrogatepass") as f:
        f.write(text)
    out = os.path.join(work, f"out_{k}")
    cmd = [binary, "run", case, "--threads", "1", "--out", out]
    start = time.time()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        so, se = p.communicate(timeout=timeout)
        hung = False
    except subprocess.TimeoutExpired:
        p.kill()
        so, se = p.communicate()
        hung = True
    elapsed = time.time() - start
    shutil.rmtree(out, ignore_errors=True)
    err = se.decode("utf-8", "replace")
    # The start line, progress lines and the heartbeat (at least every 5 s) all count.
    progress = bool(so.strip() or err.strip())
    verdict = None
    if hung:
        verdict = None if progress else "hang"
    elif p.returncode == 101:
        verdict = "panic"
    elif p.returncode < 0 or p.returncode > 3:
        verdict = f"signal/exit {p.returncode}"
    elif p.returncode == 1:
        # Progress before the error (the settled start's announcement, the heartbeat) is
        # not part of the message.
        lines = [l for l in err.strip().split("\n")
                 if l.strip() and not PROGRESS.match(l)]
        if len(lines) != 1:
            verdict = "exit-1 message not one line"
        elif os.path.basename(case) not in lines[0]:
            verdict = "exit-1 message does not name the file"
    code = "killed at 10 s (with progress)" if hung else str(p.returncode)
    os.remove(case)
    return k, name, text, code, verdict, elapsed, err.strip()[:300]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("--count", type=int, default=10000)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=10.0)
    ap.add_argument("--keep", default="fuzz_failures")
    a = ap.parse_args()
    binary = os.path.abspath(a.binary)
    rng = random.Random(a.seed)
    seeds = seed_texts()
    jobs = []
    for k in range(a.count):
        name, text = rng.choice(seeds)
        for _ in range(rng.randint(1, 3)):
            text = mutate(text, rng)
        jobs.append((k, name, text))
    codes = collections.Counter()
    defects = collections.Counter()
    field_named = 0
    unnamed = []
    exit1 = 0
    slowest = 0.0
    with tempfile.TemporaryDirectory() as work, cf.ThreadPoolExecutor(a.jobs) as pool:
        futures = [pool.submit(run_one, binary, work, k, n, t, a.timeout) for k, n, t in jobs]
        for f in cf.as_completed(futures):
            k, name, text, code, verdict, elapsed, err = f.result()
            codes[code] += 1
            slowest = max(slowest, elapsed)
            if code == "1":
                exit1 += 1
                # `error: FILE: FIELD[ = VALUE]: message`, or a line number for syntax.
                rest = err.split(".toml: ", 1)[-1]
                if re.match(r"[\w.\-]+( = .*?)?: ", rest) or re.search(r"line \d+", rest):
                    field_named += 1
                elif len(unnamed) < 20:
                    unnamed.append(err)
            if verdict:
                defects[verdict] += 1
                os.makedirs(a.keep, exist_ok=True)
                path = os.path.join(a.keep, f"{verdict.replace(' ', '_')}_{k}.toml")
                with open(path, "w", encoding="utf-8", errors="surrogatepass") as g:
                    g.write(text)
                print(f"DEFECT {verdict}: {path} (seed {name}) :: {err[:200]}", flush=True)
    print(f"{a.count} mutated cases, seed {a.seed}, {a.jobs} jobs, timeout {a.timeout} s")
    for code, n in sorted(codes.items()):
        print(f"  exit {code}: {n}")
    print(f"  exit-1 messages naming a field, a key path or a line: {field_named} of {exit1}")
    print(f"  slowest run: {slowest:.1f} s")
    for e in unnamed:
        print(f"  no field named: {e}")
    print(f"  defects: {dict(defects) if defects else 0}")
    return 1 if defects else 0


if __name__ == "__main__":
    raise SystemExit(main())
