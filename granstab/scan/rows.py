"""The records a scan writes, each defined once: `Row` (one cluster of clusters.*) and `ParticleRow` (one particle of
particles.*). Their Arrow schemas are derived from their fields (`schema`); every table of rows, whether one
`analyze` per cluster (`rows_table`) or a batch's columns (`columns_table`), is built against it.
"""
from __future__ import annotations

import typing
from dataclasses import dataclass, fields

import numpy as np


@dataclass(frozen=True)
class Row:
    """One cluster: its centre and members (particle indices into the scanned packing: the scan folder's
    packing.npz, whose names particles.* lists in the same order), the path that solved it ("analyze", "batched",
    "batched-values"), its size, the verdict (verdicts.Verdict: counts, proof, reason; `metric_robust` None for one
    metric), the lowest non-rigid stability eigenvalue over its branches, the error estimates and the seconds it
    took."""

    center: int
    members: list[int]
    n_particles: int
    path: str
    n_contacts: int
    n_sliding: int
    branches: str
    n_branches: int
    lambda_min: float
    consistent_negative: int
    consistent_positive: int
    verdict: str
    sufficient: bool
    insufficient_because: str
    metric_robust: bool | None
    zero_margin: float
    eigen_residual: float
    rigid_leakage: float
    reason: str
    seconds: float
    mechanism: str = ""
    work_parts: list[float] | None = None
    rim_share: float | None = None
    elastic_control: str = ""
    fixed_control: str = ""
    data_robust: str = ""                   # issue 42 (scan/uncertain.py): holds / depends / undecided, "" without
    robust_margin: float | None = None      # a band; the factor of the band the bound proves (> 1: holds)
    counterexample: list[float] | None = None   # depends: the forces (flat, d a contact) of the cluster's scene,
    #                                             then its moved centres and points (uncertainty.flat_counterexample)
                                                # (clusters.cluster, its contact order) that give the other verdict

    @classmethod
    def analyzed(cls, center, members, verdict, *, n_contacts: int, n_sliding: int, lambda_min: float,
                 eigen_residual: float, rigid_leakage: float, seconds: float, attribution: dict | None = None) -> Row:
        """The row of an `analyze` of the cluster (its `Verdict` and numbers)."""
        return cls(center=center, members=members, n_particles=len(members), path="analyze", n_contacts=n_contacts,
                   n_sliding=n_sliding, branches=verdict.branches, n_branches=verdict.n_branches,
                   lambda_min=lambda_min, consistent_negative=verdict.consistent_negative,
                   consistent_positive=verdict.consistent_positive, verdict=verdict.verdict,
                   sufficient=verdict.sufficient, insufficient_because=",".join(verdict.insufficient_because),
                   metric_robust=verdict.metric_robust,
                   zero_margin=np.nan if verdict.zero_margin is None else verdict.zero_margin,
                   eigen_residual=eigen_residual, rigid_leakage=rigid_leakage, reason=verdict.reason,
                   seconds=seconds, **(attribution or {}))

    @classmethod
    def failed(cls, center, members, reason: str, seconds: float) -> Row:
        """The row of a cluster whose analysis failed (verdict "error", counts -1, numbers NaN): a row, never a
        lost cluster."""
        return cls(center=center, members=members, n_particles=len(members), path="analyze", n_contacts=-1,
                   n_sliding=-1, branches="none", n_branches=0, lambda_min=np.nan, consistent_negative=-1,
                   consistent_positive=-1, verdict="error", sufficient=False, insufficient_because="error",
                   metric_robust=None, zero_margin=np.nan, eigen_residual=np.nan, rigid_leakage=np.nan,
                   reason=" ".join(reason.split()), seconds=seconds)


@dataclass(frozen=True)
class ParticleRow:
    """One particle of the map: its name, the verdict of its own cluster ('' if it was no centre), the fraction of
    the clusters containing it that are unstable (NaN: none contains it) and how many contain it."""

    name: str
    own_verdict: str
    unstable_fraction: float
    n_clusters: int


ROW_COLUMNS = tuple(f.name for f in fields(Row))
NAN_IS_NULL = ("rim_share", "robust_margin")     # columns whose NaN in a batch's numpy columns means "none" (null)


def schema(record):
    """The Arrow schema of a record's fields, from their types: int → int64, float → float64, str → string,
    bool → bool (`X | None`: nullable X), list[X] → list of X."""
    import pyarrow as pa
    scalars = {int: pa.int64(), float: pa.float64(), str: pa.string(), bool: pa.bool_()}

    def arrow(kind):
        if typing.get_origin(kind) is list:
            return pa.list_(arrow(typing.get_args(kind)[0]))
        if kind in scalars:
            return scalars[kind]
        return arrow(next(k for k in typing.get_args(kind) if k is not type(None)))

    hints = typing.get_type_hints(record)
    return pa.schema([pa.field(f.name, arrow(hints[f.name])) for f in fields(record)])


def rows_table(rows: list[Row]):
    """Rows as an Arrow table of `schema(Row)` (made where the chunk ran, so that the client only writes it)."""
    import pyarrow as pa
    return pa.table({key: [getattr(r, key) for r in rows] for key in ROW_COLUMNS}, schema=schema(Row))


def columns_table(columns: dict):
    """Rows given as columns, one per field of `Row` (numpy arrays; members as (flat values, offsets); work_parts
    (rows, 5)), as an Arrow table of `schema(Row)`."""
    import pyarrow as pa
    if set(columns) != set(ROW_COLUMNS):
        raise ValueError(f"columns_table: the fields of Row, got {sorted(set(columns) ^ set(ROW_COLUMNS))} wrong")
    kinds = schema(Row)
    values, offsets = columns["members"]
    members = pa.ListArray.from_arrays(pa.array(offsets, type=pa.int32()),
                                       pa.array(values, type=kinds.field("members").type.value_type))
    def array(key):
        value = columns[key]
        if key == "members":
            return members
        if isinstance(value, np.ndarray) and value.ndim == 2:       # (rows, k): a list each, null where all NaN
            return pa.ListArray.from_arrays(pa.array(np.arange(0, value.size + 1, value.shape[1]), type=pa.int32()),
                                            pa.array(value.ravel(), type=kinds.field(key).type.value_type),
                                            mask=pa.array(np.isnan(value).all(axis=1)))
        return pa.array(value, type=kinds.field(key).type, from_pandas=key in NAN_IS_NULL)

    return pa.table({key: array(key) for key in ROW_COLUMNS}, schema=kinds)


def concat_rows(tables: list):
    """Row tables (rows_table, columns_table) as one; none: an empty one."""
    import pyarrow as pa
    return pa.concat_tables(tables) if tables else rows_table([])
