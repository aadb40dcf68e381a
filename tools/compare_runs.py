#!/usr/bin/env python3
"""Compares two run folders written by `mps run`: every VTU array bit for bit and every
number of every CSV file, at the precision the coarser of the two files printed it.

usage: compare_runs.py OLD_DIR NEW_DIR [--expect-changed FILE:COLUMN ...]
Prints one line per file and exits 1 if anything differs. Arrays or columns present in
only one of the two runs are listed (a renamed or new field), not counted as differences.
Columns named with --expect-changed (a named bug fix) are reported, not counted.
"""
import csv
import math
import os
import re
import struct
import sys


def vtu_arrays(path):
    """Name -> raw bytes of every appended array of a VTU file (UInt64 block headers)."""
    data = open(path, "rb").read()
    marker = b'<AppendedData encoding="raw">\n_'
    start = data.index(marker) + len(marker)
    head = data[:start].decode("utf-8", "replace")
    out = {}
    for line in head.splitlines():
        if 'format="appended"' not in line:
            continue
        name = re.search(r'Name="([^"]*)"', line)
        name = name.group(1) if name else "Points"
        off = int(re.search(r'offset="(\d+)"', line).group(1))
        at = start + off
        (length,) = struct.unpack("<Q", data[at:at + 8])
        typ = re.search(r'type="([^"]*)"', line).group(1)
        out[name] = (typ, data[at + 8:at + 8 + length])
    return out


def as_numbers(typ, raw):
    fmt = {"Float64": "d", "Float32": "f", "Int32": "i", "Int64": "q", "UInt8": "B",
           "UInt32": "I", "UInt16": "H"}[typ]
    n = len(raw) // struct.calcsize(fmt)
    return struct.unpack("<%d%s" % (n, fmt), raw)


def compare_vtu(a, b):
    va, vb = vtu_arrays(a), vtu_arrays(b)
    problems, notes = [], []
    for name in sorted(set(va) | set(vb)):
        if name not in va or name not in vb:
            notes.append("%s only in %s" % (name, "old" if name in va else "new"))
            continue
        (ta, ra), (tb, rb) = va[name], vb[name]
        if ta == tb and ra == rb:
            continue
        if ta != tb:
            # A type change (e.g. Int32 -> UInt8) keeps the values: compare them exactly.
            if as_numbers(ta, ra) == as_numbers(tb, rb):
                continue
        problems.append("array %s differs" % name)
    return problems, notes


def decimals(token):
    """How a number was printed: ('e', k) for k mantissa decimals, ('f', k), or None."""
    m = re.fullmatch(r"[-+]?\d+(?:\.(\d*))?[eE][-+]?\d+", token)
    if m:
        return ("e", len(m.group(1) or ""))
    m = re.fullmatch(r"[-+]?\d+(?:\.(\d*))?", token)
    if m:
        return ("f", len(m.group(1) or ""))
    return None


def same_number(x, y):
    """True when two printed numbers agree at the precision of the coarser one."""
    if x == y:
        return True
    try:
        fx, fy = float(x), float(y)
    except ValueError:
        return False
    if math.isnan(fx) and math.isnan(fy):
        return True
    if fx == fy:
        return True
    dx, dy = decimals(x), decimals(y)
    if dx is None or dy is None:
        return False
    # Reprint the finer one the way the coarser one was printed.
    for (coarse, fine) in ((x, fy), (y, fx)):
        style, k = decimals(coarse)
        again = ("%.*e" if style == "e" else "%.*f") % (k, fine)
        if float(again) == float(coarse):
            return True
    return False


def compare_csv(a, b, expected=()):
    ra = list(csv.reader(open(a)))
    rb = list(csv.reader(open(b)))
    problems, notes = [], []
    if not ra or not rb:
        return (["empty file"] if bool(ra) != bool(rb) else []), notes
    ha, hb = ra[0], rb[0]
    common = [c for c in ha if c in hb]
    for c in ha:
        if c not in hb:
            notes.append("column %s only in old" % c)
    for c in hb:
        if c not in ha:
            notes.append("column %s only in new" % c)
    if len(ra) != len(rb):
        problems.append("%d rows vs %d" % (len(ra) - 1, len(rb) - 1))
        return problems, notes
    ia = {c: ha.index(c) for c in common}
    ib = {c: hb.index(c) for c in common}
    bad = 0
    changed = set()
    for k, (x, y) in enumerate(zip(ra[1:], rb[1:])):
        for c in common:
            if not same_number(x[ia[c]].strip(), y[ib[c]].strip()):
                if c in expected:
                    changed.add(c)
                    continue
                if bad < 3:
                    problems.append("row %d column %s: %s vs %s" % (k + 1, c, x[ia[c]], y[ib[c]]))
                bad += 1
    for c in sorted(changed):
        notes.append("column %s changed (expected: named fix)" % c)
    if bad > 3:
        problems.append("... %d differing values in all" % bad)
    return problems, notes


def main():
    old, new = sys.argv[1], sys.argv[2]
    expected = {}
    rest = sys.argv[3:]
    while rest:
        if rest[0] == "--expect-changed" and len(rest) > 1:
            f, c = rest[1].split(":", 1)
            expected.setdefault(f, set()).add(c)
            rest = rest[2:]
        else:
            sys.exit("unknown argument %s" % rest[0])
    failed = False
    vtu_same, vtu_notes = 0, set()
    files = sorted(set(os.listdir(old)) | set(os.listdir(new)))
    for f in files:
        if not (f.endswith(".vtu") or f.endswith(".csv")):
            continue
        pa, pb = os.path.join(old, f), os.path.join(new, f)
        if not os.path.exists(pa) or not os.path.exists(pb):
            print("  %-36s only in %s" % (f, "old" if os.path.exists(pa) else "new"))
            if f.endswith(".vtu"):
                failed = True
            continue
        if f.endswith(".vtu"):
            problems, notes = compare_vtu(pa, pb)
        else:
            problems, notes = compare_csv(pa, pb, expected.get(f, ()))
        if f.endswith(".vtu") and not problems:
            vtu_same += 1
            vtu_notes |= set(notes)
            continue
        status = "DIFFERENT" if problems else "identical"
        extra = ("; " + "; ".join(notes)) if notes else ""
        print("  %-36s %s%s" % (f, status, extra))
        for p in problems:
            print("      " + p)
        failed |= bool(problems)
    if vtu_same:
        extra = ("; " + "; ".join(sorted(vtu_notes))) if vtu_notes else ""
        print("  %-36s identical (every array, bit for bit)%s" % ("%d VTU files" % vtu_same, extra))
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
