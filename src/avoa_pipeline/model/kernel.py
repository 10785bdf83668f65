"""Compiled time-stepping of the paper's 1-RC model for a whole population of candidates.

Why hand-written: the load scenarios make the battery current depend on the terminal voltage at
every step, so the recursion is sequential in time and no scipy filter expresses it; a Python
loop over ~6,000 samples × 20 candidates × 500 iterations would take hours. numba compiles the
loop once (cached on disk).

Per sample k (eqs. 3-6 of Fahmy et al.; current positive = discharge):

    Vocv_k  = Vnom·SOC_k / (1 − β(1 − SOC_k))                     eq. 5
    Vt_k    = Vocv_k − Vtr_k − R0·I_k                              eq. 4
    I_k     = Ip_k + Vt_k·G_load  → solved exactly, not lagged:
              Vt_k = (Vocv_k − Vtr_k − R0·Ip_k) / (1 + R0·G_load)
    Vtr_k+1 = a·Vtr_k + Rtr·(1 − a)·I_k,   a = exp(−Ts/τ)          eq. 3
    SOC_k+1 = SOC_k − I_k·Ts / (3600·Q)                           eq. 6 (forward Euler)

Speed: with the load, the chain SOC → Vocv (a division) → Vt → I → SOC is carried from sample to
sample, so one candidate at a time is latency-bound. The population kernel therefore steps all
candidates of a block together (time outer, candidates inner), which gives the CPU independent
work, in SIMD lanes (a fit block's seeds stepped together give it 30 to 600 rows per call);
blocks run on the numba threads. The single-candidate kernel (a fit run alone) keeps its state
in scalars. All share one inlined step, :func:`_step`, so they agree bit for bit. Measured by
``benchmarks/bench_kernel.py``.

``P`` holds *effective* parameters (fade already applied), one candidate per row, in the column
order of :data:`avoa_pipeline.model.battery.PARAM_NAMES`: vnom, q, vdis, r0, rtr, tau.
"""

from __future__ import annotations

import numba as nb
import numpy as np

VNOM, Q, VDIS, R0, RTR, TAU = range(6)

# The candidates' loop of `_score_block` runs in SIMD lanes (4 doubles; LLVM unrolls it to 16
# rows a trip, then 8) and the rows left over ran one by one, each a latency-bound chain; fewer
# than 16 rows all did. So a block of at least LANES rows is padded with copies of its last row
# (their values dropped) to a multiple of LANES, and to 2 LANES at least. Measured with
# benchmarks/bench_kernel.py's timing on scenario 4 (5,701 samples, one thread): 30 rows (one
# point per seed of a 30-seed block: Nelder–Mead, RUN) 195 us a call, 32 rows 168 us; 8 rows
# 129 us, 16 rows 97 us; below 8 rows the lone chains are cheaper than 16 lanes (1 row 57 us).
LANES = 8


def paper_beta(vnom, vdis, soc1):
    """The OCV curvature β of eq. 5 from Vocv(SOC1) = Vdis: β = (1 − Vnom·SOC1/Vdis) / (1 − SOC1),
    SOC1 = Qdis/Q. Scalars or arrays; the one place the paper's β is written (the compiled
    kernel calls its numba twin, the library, the gap check and the real-cell experiments this)."""
    return (1.0 - vnom * soc1 / vdis) / (1.0 - soc1)


_paper_beta = nb.njit(cache=True)(paper_beta)


@nb.njit(cache=True)
def _coefficients(P, ts, qdis, g_load, dynamics):
    """Per-candidate constants: Vnom, 1−β, β, R0, a, b = Rtr(1−a), 1/(1+R0·G), dq = Ts/(3600·Q),
    kq = dq·G/(1+R0·G) (SOC change per volt of Vocv − Vtr − R0·Ip through the load),
    kv = kq·Vnom."""
    m = P.shape[0]
    C = np.empty((10, m))
    for c in range(m):
        soc1 = qdis / P[c, Q]
        beta = _paper_beta(P[c, VNOM], P[c, VDIS], soc1)
        a = np.exp(-ts / P[c, TAU]) if dynamics else 0.0
        C[0, c] = P[c, VNOM]
        C[1, c] = 1.0 - beta
        C[2, c] = beta
        C[3, c] = P[c, R0]
        C[4, c] = a
        C[5, c] = P[c, RTR] * (1.0 - a) if dynamics else 0.0
        C[6, c] = 1.0 / (1.0 + P[c, R0] * g_load)
        C[7, c] = ts / (3600.0 * P[c, Q])
        C[8, c] = C[7, c] * g_load * C[6, c]
        C[9, c] = C[8, c] * C[0, c]
    return C


@nb.njit(inline="always")
def _step(s, vtr, ipk, vnom, omb, beta, r0, a, b, inv_den, dq, kq, kv, g_load, load):
    """One sample: (Vt, I, SOC and Vtr of the next sample). Every kernel steps through this one
    function (inlined), so all give the same numbers bit for bit.

    With the load, SOC − dq·I is regrouped so that only the OCV division and one subtraction stay
    on the sample-to-sample chain (≈1.5× faster for one candidate; the same value up to rounding).
    Without it the current is the cycler's and Vt leaves the SOC recursion altogether.
    """
    r = s / (omb + beta * s)
    vt = (vnom * r - vtr - r0 * ipk) * inv_den
    if load:
        i = ipk + vt * g_load
        s_next = (s - dq * ipk + kq * (vtr + r0 * ipk)) - kv * r
    else:
        i = ipk
        s_next = s - ipk * dq
    return vt, i, s_next, a * vtr + b * i


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _score_block(P, ip, vmeas, ts, soc0, qdis, g_load, dynamics, out):
    """Write the ISE of every row of ``P`` into ``out``: time outer, candidates inner, so the
    candidates' independent chains overlap in SIMD lanes; one loop per load case so no branch
    sits inside.

    Written for the vectoriser: the state (SOC, Vtr, the accumulated error) lives in one (3, m)
    array and the constants in one (10, m) array (with thirteen separate arrays LLVM gives up on
    its runtime alias checks and steps one candidate at a time), and ``error_model="numpy"``
    keeps the exception branch of a division by zero out of the loop (such a row scores inf or
    NaN, which the optimizers count as +inf, instead of raising). Each lane does the scalar
    code's IEEE operations in the same order, so every row's value is bit for bit what
    :func:`ise_one` gives it, whatever the other rows (tested).
    """
    rows = P.shape[0]
    m = rows if rows < LANES else max(2 * LANES, -(-rows // LANES) * LANES)  # see LANES
    if m != rows:
        padded = np.empty((m, P.shape[1]))
        padded[:rows] = P
        padded[rows:] = P[rows - 1]
        P = padded
    C = _coefficients(P, ts, qdis, g_load, dynamics)
    S = np.zeros((3, m))  # SOC, Vtr, accumulated squared error
    S[0, :] = soc0
    if g_load != 0.0:
        for k in range(ip.shape[0]):
            ipk, vk = ip[k], vmeas[k]
            for c in range(m):
                vt, _, S[0, c], S[1, c] = _step(
                    S[0, c], S[1, c], ipk, C[0, c], C[1, c], C[2, c], C[3, c], C[4, c],
                    C[5, c], C[6, c], C[7, c], C[8, c], C[9, c], g_load, True,
                )  # fmt: skip
                S[2, c] += (vt - vk) * (vt - vk)
    else:
        for k in range(ip.shape[0]):
            ipk, vk = ip[k], vmeas[k]
            for c in range(m):
                vt, _, S[0, c], S[1, c] = _step(
                    S[0, c], S[1, c], ipk, C[0, c], C[1, c], C[2, c], C[3, c], C[4, c],
                    C[5, c], C[6, c], C[7, c], C[8, c], C[9, c], 0.0, False,
                )  # fmt: skip
                S[2, c] += (vt - vk) * (vt - vk)
    out[:] = S[2, :rows]


@nb.njit(cache=True, parallel=True, nogil=True)
def ise_population(P, ip, vmeas, ts, soc0, qdis, g_load, dynamics, n_blocks):
    """Integral square error, eq. 13, of every row of ``P`` against ``vmeas``."""
    m = P.shape[0]
    out = np.empty(m)
    size = (m + n_blocks - 1) // n_blocks
    for j in nb.prange(n_blocks):
        lo = j * size
        hi = min(m, lo + size)
        if lo < hi:
            _score_block(P[lo:hi], ip, vmeas, ts, soc0, qdis, g_load, dynamics, out[lo:hi])
    return out


@nb.njit(cache=True, nogil=True)
def ise_serial(P, ip, vmeas, ts, soc0, qdis, g_load, dynamics):
    """As :func:`ise_population` on the calling thread only (no thread pool, GIL released)."""
    out = np.empty(P.shape[0])
    _score_block(P, ip, vmeas, ts, soc0, qdis, g_load, dynamics, out)
    return out


@nb.njit(cache=True, nogil=True, inline="always")
def _effective(x, free, base, fade):
    p = base.copy()
    for j in range(free.shape[0]):
        p[free[j]] = x[j]
    return (p * fade).reshape(1, -1)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def ise_one(x, free, base, fade, ip, vmeas, ts, soc0, qdis, g_load, dynamics):
    """ISE of one candidate ``x`` of free parameters (columns ``free`` of the fresh-cell vector
    ``base``; effective parameters = fresh × ``fade``): the single-candidate path of a fit run
    alone (Nelder–Mead, RUN). The state lives in scalars: in the block kernel it lives in arrays,
    and for one candidate every sample then waits for a store and a reload on the
    sample-to-sample chain. Division by zero as in :func:`_score_block` (inf or NaN, no raise).
    """
    C = _coefficients(_effective(x, free, base, fade), ts, qdis, g_load, dynamics)[:, 0]
    vnom, omb, beta, r0, a, b, inv_den, dq, kq, kv = C
    load = g_load != 0.0
    s, vtr, acc = soc0, 0.0, 0.0
    for k in range(ip.shape[0]):
        vt, _, s, vtr = _step(
            s, vtr, ip[k], vnom, omb, beta, r0, a, b, inv_den, dq, kq, kv, g_load, load
        )
        acc += (vt - vmeas[k]) * (vt - vmeas[k])
    return acc


@nb.njit(cache=True)
def simulate_one(p, ip, ts, soc0, qdis, g_load, dynamics):
    """Traces (Vt, I, SOC, Vtr), shape (4, n), of one row ``p`` of effective parameters."""
    C = _coefficients(p.reshape(1, -1), ts, qdis, g_load, dynamics)[:, 0]
    vnom, omb, beta, r0, a, b, inv_den, dq, kq, kv = C
    load = g_load != 0.0
    traces = np.empty((4, ip.shape[0]))
    s, vtr = soc0, 0.0
    for k in range(ip.shape[0]):
        traces[2, k], traces[3, k] = s, vtr
        traces[0, k], traces[1, k], s, vtr = _step(
            s, vtr, ip[k], vnom, omb, beta, r0, a, b, inv_den, dq, kq, kv, g_load, load
        )
    return traces
