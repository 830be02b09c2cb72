"""The paper's examples in report order: name → its report module (`run`, `steps`, `markdown` section)."""
from . import four_disk, gear, sliding_contact, two_particle

EXAMPLES = {"two-particle": two_particle, "gear": gear, "four-disk": four_disk, "sliding-contact": sliding_contact}
NAMES = tuple(EXAMPLES)
