"""The paper's examples in report order: name → its report module (`run`, `steps`, `markdown` section)."""
from . import four_disk_report as four_disk
from . import gear_report as gear
from . import sliding_contact_report as sliding_contact
from . import two_particle_report as two_particle

EXAMPLES = {"two-particle": two_particle, "gear": gear, "four-disk": four_disk, "sliding-contact": sliding_contact}
NAMES = tuple(EXAMPLES)
