"""`.ci/run` collects the browser part from tests/app alone (docs/testing.md): a browser test elsewhere would never run."""
import re

from helpers import ROOT, TESTS


def test_every_browser_test_lives_in_tests_app():
    marked = [p.relative_to(TESTS).as_posix() for p in TESTS.rglob("test_*.py")
              if re.search(r"pytest\.mark\.browser\b", p.read_text(encoding="utf-8"))]
    assert marked and all(m.startswith("app/") for m in marked), marked
    assert '-m "browser and not serial" tests/app' in (ROOT / ".ci" / "run").read_text(encoding="utf-8")
