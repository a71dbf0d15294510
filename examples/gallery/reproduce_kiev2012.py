"""The Kiev 2012 seminar's tables beside ours (docs/reproduction.md): Algorithm 1, the eq 28
sensitivity study and the Kalman table. The narrative's numbers use 45 000 runs per case."""

from _common import OUT, SMALL, run

sizes = ["--runs", "1000", "--kalman-runs", "200", "--workers", "1"] if SMALL else []
run("reproduce", "kiev2012", "--out", str(OUT / "report"), *sizes)
