"""Frame sequences (issue 27): does instability come before rearrangement? `track` reads every frame of a
sequence, computes each frame's row and its particles' predictors, and between frames the non-affine motion,
the contact changes and the stress-drop events (docs/track.md).

    granstab.track.track("DataAnnulus/10", "out/", mu=0.5, scan=True, frames="1:20:2")

CONTRACT (what `granstab.track.predict` and `.figures` and the explorer read; "granstab track 1")
------------------------------------------------------------------------------------------------
DIR/frames.parquet — one row a selected frame, in order:
    frame (int64: 0-based position in the input's frame list), step (float64: the reader's key of that frame, by
    which --frames selects, as export's — annulus frame number, LAMMPS/DataSim timestep, table frame, MercuryDPM time; NaN: one
    frame), n_particles (rattlers included), n_rattlers, n_contacts, n_sliding, dim, stress (list<float64>, d×d row
    by row: σ = (1/V) Σ f⊗b, tension positive), pressure (−tr σ / d), shear_stress (√(½ s:s), s = dev sym σ),
    stress_ratio (shear_stress / pressure), volume, volume_from (the cell, or the centres' convex hull), cell
    (list<float64>, d×d lattice rows; empty: no cell), mean_contact_distance, z (2M / particles with a contact),
    mobilised_fraction (contacts at yield / contacts), import_warnings (list<string>), import_report (JSON text),
    lambda_min_unloading, lambda_min_loading (float64, NaN), n_negative_unloading, n_negative_loading (int64,
    −1; sparse path: among the max(6, soft_modes, 1 % of the dofs) lowest eigenpairs computed), whole_verdict, whole_method,
    whole_reason ("not determined because …" where not a proof), whole_proven, whole_hinges_on_tolerance (int64
    1/0, −1), soft_modes (how many), soft_modes_from, soft_spots_count, soft_spots_frictionless_lambda_max,
    soft_spots_frictionless_method ("dense", "shift-invert, count checked", "lanczos"),
    soft_spots_frictionless_residual (max ‖Dv − λv‖), soft_spots_branch_count       [--whole; else the fill]
    scan_clusters, scan_unstable, scan_unstable_nonboundary (int64, −1), scan_verdicts (JSON text)   [--scan]
    rigid_largest_particles (int64, −1), rigid_largest_fraction (float64, NaN)                   [--rigidity]
    n_made, n_broken, n_slid (float64: contacts from this frame to frame + W; NaN for the last W frames),
    seconds_read, seconds_frame, seconds_whole, seconds_scan, seconds_rigidity.
DIR/particles.parquet — one row a frame × particle (rattlers kept), frames in order:
    frame (int64), name (string: the particle's id, by which frames are matched), x, y[, z] (float64),
    rattler (bool), coordination (int64), mobilised_fraction, force_magnitude (mean |f| of its contacts),
    sliding_distance (to the nearest contact point at yield; NaN: none in the frame), random (seeded uniform),
    unstable_fraction, unstable_fraction_nonboundary, cluster_lambda_min         [--scan; NaN otherwise]
    soft_participation (mean share of the lowest consistent modes' squared translation), soft_spots_frictionless,
    soft_spots_branch (the same in the lowest 1 % of modes, softspots.py)           [--whole; else NaN]
    in_largest_rigid_cluster (1.0 / 0.0)                                     [--rigidity; NaN otherwise]
    d2min (Falk & Langer over the window that starts at this frame, length², not normalised),
    contacts_made, contacts_broken, contacts_changed (= made + broken), contacts_slid (float64 counts; all NaN
    where the window runs past the last frame or the particle is gone at frame + W).
DIR/events.json — a list of {frame, next_frame, quantity, drop, relative_drop}: drops of `quantity`
    (shear_stress or stress_ratio) from one selected frame to the next larger than threshold × the run's mean.
DIR/summary.json — contract, source, frames_in_input, frames, import_warnings (the import's warnings of the run,
    once each: io.validation.run_warnings), positions, steps, options, defaults, units,
    windows {window, d2min_radius, d2min_radius_from, last_frames_without_window}, thresholds {event_quantity,
    event_threshold, run_mean, rule}, events (count), inertial_number (null: not known) and its note,
    cost {seconds, stages {read, frame, whole, scan, rigidity, between}, resumed, frames_this_run, workers},
    after {predict, figures} when they were asked for.
DIR/scans/frame-NNNNNN/ — with --scan, each frame's scan folder (granstab.scan.read_map opens it).
DIR/parts/, DIR/options.json — the run's resumable state.
"""
from .run import track

__all__ = ["track"]
