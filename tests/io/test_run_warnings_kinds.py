"""Import warnings of a run are printed once each (io.validation.run_warnings): two warnings of different kinds that
both start `N contact(s) ...` stay two lines (a greedy parenthesis pattern once merged them, so that a tension
warning of one frame of the superquadric loading run was lost under the friction-cone warning)."""
from granstab.io.validation import run_warnings

CONE = "{n} contact(s) outside the friction cone ({p} %, |f_t|/(μ f_n) up to {r}): projected onto the cone ({ids})"
TENSION = "2 contact(s) with f_n <= 0 carrying a force (tension): treated as elastic (152-227, 194-102)"


def test_warnings_of_two_kinds_are_both_kept_and_counted_apart():
    frames = [(k, [CONE.format(n=k + 2, p=k + 1, r=1.5 + k, ids=f"{k}-9")]) for k in range(4)]
    frames[1][1].append(TENSION)
    out = run_warnings(frames)
    assert len(out) == 2
    assert out[0].startswith("2 contact(s) outside") and out[0].endswith("[frame 0; one like it in 4 of 4 frames]")
    assert out[1] == TENSION + " [frame 1; one like it in 1 of 4 frames]"
