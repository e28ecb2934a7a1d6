"""Write a generated circuit (``path.kind: generated``) as a racetrack-database CSV.

    .venv/bin/python tools/write_circuit.py --seed 7 --out circuit-7.csv
    .venv/bin/cosim run track --set path.file=circuit-7.csv    # the same circuit, as a file

The file is the one ``cosim run generated-circuit --set path.seed=7`` drives
(:mod:`tracker.paths.generated_circuit`), in the layout a user's own circuit comes in.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tracker.paths.generated_circuit import circuit_csv, generated_circuit


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, required=True, help="the generator's seed")
    parser.add_argument("--out", type=Path, required=True, help="CSV to write (not replaced)")
    args = parser.parse_args()
    if args.out.exists():
        parser.error(f"--out {str(args.out)!r} exists: expected a new file")
    args.out.write_text(circuit_csv(generated_circuit(args.seed)))
    print(args.out)


if __name__ == "__main__":
    main()
