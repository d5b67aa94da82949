#!/usr/bin/env python3
"""Seed corpora for the cargo-fuzz targets in fuzz/ (written, never copied from data).

    python3 scripts/fuzz_corpus.py        # writes fuzz/corpus/{suite,control,signal,csv}/

suite/control: the repository's suites/*.toml (control suites are those with
[[controller]]); signal: the signal specs the suites use (twin:SPEC, eq318:SPEC) and the
grammar's examples from src/data/signal.rs; csv: small recordings in the forms the reader
accepts, each behind the target's option byte (columns, delimiter, resampling).
"""
import hashlib
import math
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parent.parent
CORPUS = ROOT / "fuzz" / "corpus"

EXAMPLES = [
    "2.5 + sine:freq=10,amp=2",
    "sine:freq=10,amp=2,offset=2.5",
    "chirp:f0=10,f1=1,duration=8,amp=2,law=log,offset=2.5",
    "multisine:fmin=5,fmax=150,rms=50,period=10.92,seed=3",
    "steps:levels=0;1;2;1,hold=0.5",
    "steps:levels=0;1,hold=0.5,repeat=true",
    "triangle:freq=1,amp=2,phase=0.5,offset=1",
    "am:carrier=(sine:freq=10),envelope=(raised-cosine:min=0.3,max=1,duration=8)",
    "am:carrier=(sine:freq=10),envelope=ramp",
    "am:carrier=(sine:freq=1),envelope=(ramp:from=0,to=1,duration=1)",
    "-1*(triangle:freq=1 + 0.5)",
]


def put(target, data):
    folder = CORPUS / target
    folder.mkdir(parents=True, exist_ok=True)
    (folder / hashlib.sha1(data).hexdigest()).write_bytes(data)


def rows(sep, dec, dt, n, skip=None):
    out = [f"t{sep}u{sep}y"]
    for k in range(n):
        if k == skip:
            continue
        t = k * dt
        u = math.sin(7 * t)
        y = 0.5 * u + 0.1 * math.cos(3 * t)
        line = f"{t!r}{sep}{u:.6f}{sep}{y:.6f}"
        out.append(line.replace(".", ",") if dec == "," else line)
    return ("\n".join(out) + "\n").encode()


def main():
    specs = set(EXAMPLES)
    for path in sorted((ROOT / "suites").glob("*.toml")):
        text = path.read_bytes()
        put("control" if b"[[controller]]" in text else "suite", text)
        for value in re.findall(r'"([^"]*)"', text.decode()):
            for part in value.split(" | "):
                for prefix in ("twin:", "eq318:"):
                    if part.startswith(prefix):
                        specs.add(part[len(prefix):])
    for spec in sorted(specs):
        put("signal", spec.encode())
    # Option byte: high nibble columns (0 = t,u,y), bit 3 resample, low bits delimiter
    # (0 auto, 1 ',', 2 ';', 3 tab, 4 whitespace).
    put("csv", b"\x00" + rows(",", ".", 0.001, 20))
    put("csv", b"\x02" + rows(";", ",", 0.01, 12))
    put("csv", b"\x03" + rows("\t", ".", 0.5, 10))
    put("csv", b"\x04" + rows("   ", ".", 0.001, 10))
    put("csv", b"\x08" + rows(",", ".", 0.001, 16, skip=5))
    put("csv", b"\x00\xef\xbb\xbf" + rows(",", ".", 0.002, 9))
    named = rows(",", ".", 0.001, 10).replace(b"t,u,y", b"t_s,u_V,y_mm", 1)
    put("csv", b"\x10" + named)
    for target in ("suite", "control", "signal", "csv"):
        print(f"{target}: {len(list((CORPUS / target).iterdir()))} seeds")


if __name__ == "__main__":
    main()
