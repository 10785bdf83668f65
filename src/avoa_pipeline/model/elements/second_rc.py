"""A second RC branch: a slower (or faster) relaxation than the base's one branch (the paper's
Sec. 2.1 discussion [58]; docs/gap-diagnosis.md)."""

from __future__ import annotations

import numpy as np

from .element import Element, Export, Kernel, Param, Piece, Signature, State, TableLaw, View

R_LIMITS = (0.0, 2.0)
R_WHY = "0-2 Ω: above the resistance of any cell this library models (mΩ to about 1 Ω)"
TAU_LIMITS = (0.05, 2e4)
TAU_WHY = "50 ms (a logger's fastest useful step) to 5.6 h"


def rc_piece(j: int):
    """RC branch ``j`` for the PyBaMM export: R_j and τ_j as constants (the base's branch 1 too)."""

    def piece(p) -> Piece:
        return Piece(
            constants=((f"R{j}_OHM", p[f"r{j}"], f"RC branch {j}: resistance"),
                       (f"TAU{j}_S", p[f"ltau{j}"], f"RC branch {j}: time constant R{j}·C{j}")),
            branches=((j, f"R{j}_OHM", f"TAU{j}_S"),),
        )  # fmt: skip

    return piece


def rc_kernel(j: int) -> Kernel:
    """RC branch ``j`` (j ≥ 2) as the base's branch 1 is written (``v{j}`` the voltage across it,
    ``a{j}`` its decay over the step, ``b{j}`` a hold's increment), skipped where R_j is 0."""
    return Kernel(
        columns={f"r{j}": f"r{j}", f"tau{j}": f"ltau{j}"},
        flags={f"rc{j}": f"np.any(r{j} != 0.0)"},
        branch=j,
        states={f"v{j}": State(f"v{j}", lambda p, i: p[f"r{j}"] * i)},
        code={
            "setup": f"a{j} = np.exp(-dt[0] / tau{j})\nv{j} = np.zeros(m)\nb{j} = np.zeros(m)",
            "uneven": f"a{j}[c] = np.exp(-dtk / tau{j}[c])",
            "hold_increment": f"b{j}[c] = r{j}[c] * (1.0 - a{j}[c]) * gi",
            "hold_step": f"if rc{j}:\n    for c in range(m):\n"
                         f"        v{j}[c] = a{j}[c] * v{j}[c] + b{j}[c]",
            "update": f"if rc{j}:\n"
                      f"    v{j}[c] = a{j}[c] * v{j}[c] + r{j}[c] * (1.0 - a{j}[c]) * gi",
        },
    )  # fmt: skip


def step_aligned(v: View) -> dict:
    """The mean residual after current steps, signed by the step's direction, in windows of the
    time since the step."""
    resid, sgn = v.resid, v.step_sign
    aligned = {}
    for lo, hi in ((0, 10), (10, 60), (60, 600), (600, np.inf)):
        m = (v.since >= lo) & (v.since < hi) & (sgn != 0)
        aligned[f"{lo}-{hi if np.isfinite(hi) else 'end'} s"] = (
            1e3 * float(np.mean(-sgn[m] * resid[m])) if m.any() else None
        )
    return {"step_aligned_residual_mv": aligned}


def _starts(row, imax):
    r1 = max(row["r1"], 1e-4)
    return [
        dict(r2=0.3 * r1, ltau2=row["ltau1"] - 1.0),
        dict(r2=0.3 * r1, ltau2=row["ltau1"] + 1.0),
    ]


ELEMENT = Element(
    name="second_rc",
    params={
        "r2": Param("r2_ohm", "lin", 0.0, R_LIMITS, R_WHY, prior_sd=0.1),
        "ltau2": Param("tau2_s", "log10", 2.0, TAU_LIMITS, TAU_WHY, scale="tau"),
    },
    starts=_starts,
    signature=Signature(
        "relaxation after current steps (10-600 s), beyond one time constant", step_aligned
    ),
    pybamm=Export("an RC branch: R2 [Ohm], C2 [F] = τ2/R2", rc_piece(2)),
    would_decide="a long rest after a load (relaxation over an hour or more)",
    withheld=True,
    kernel=rc_kernel(2),
    table=TableLaw("its RC branch: columns r2_ohm, tau2_s, c2_f"),
)
