"""Shared by the tests of every room (tests/<room>/, the rooms of docs/design.md). The repository's paths are
tests/helpers.py's ROOT, TESTS and DATA (tests/data stays where it is). This file puts tests/ and every room's
folder on sys.path, so that a test imports the shared helpers (helpers.py, exact_geometry.py, io_checks.py,
mp_truth.py, track_folder.py) and the builders of another room's tests (`from test_scan import planted_lattice`)
whichever folder pytest is started on; the test files' basenames are unique across the folders (pytest's default
import mode)."""
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parent
for folder in [TESTS, *sorted(p for p in TESTS.iterdir() if p.is_dir() and any(p.glob("test_*.py")))]:
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
