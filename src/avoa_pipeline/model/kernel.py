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
sample, so one candidate at a time is latency-bound (~15 ns/sample). The population kernel
therefore steps all candidates of a block together (time outer, candidates inner), which gives
the CPU independent work and lets it vectorise; blocks run on the numba threads.

``P`` holds *effective* parameters (fade already applied), one candidate per row, in the column
order of :data:`avoa_pipeline.model.battery.PARAM_NAMES`: vnom, q, vdis, r0, rtr, tau.
"""

from __future__ import annotations

import numba as nb
import numpy as np

VNOM, Q, VDIS, R0, RTR, TAU = range(6)


@nb.njit(cache=True)
def _coefficients(P, ts, qdis, g_load, dynamics):
    """Per-candidate constants: Vnom, 1−β, β, R0, a, b = Rtr(1−a), 1/(1+R0·G), Ts/(3600·Q)."""
    m = P.shape[0]
    C = np.empty((8, m))
    for c in range(m):
        soc1 = qdis / P[c, Q]
        # eq. 5 with Vocv(SOC1) = Vdis  →  β = (1 − Vnom·SOC1/Vdis) / (1 − SOC1)
        beta = (1.0 - P[c, VNOM] * soc1 / P[c, VDIS]) / (1.0 - soc1)
        a = np.exp(-ts / P[c, TAU]) if dynamics else 0.0
        C[0, c] = P[c, VNOM]
        C[1, c] = 1.0 - beta
        C[2, c] = beta
        C[3, c] = P[c, R0]
        C[4, c] = a
        C[5, c] = P[c, RTR] * (1.0 - a) if dynamics else 0.0
        C[6, c] = 1.0 / (1.0 + P[c, R0] * g_load)
        C[7, c] = ts / (3600.0 * P[c, Q])
    return C


@nb.njit(cache=True, nogil=True)
def _run_block(P, ip, vmeas, ts, soc0, qdis, g_load, dynamics, out, traces):
    """Step the candidates of ``P`` through the record.

    With ``vmeas`` given (non-empty), write each candidate's ISE into ``out``. With ``traces`` of
    shape (4, n) (one candidate only), record Vt, I, SOC and Vtr at every sample.
    """
    m = P.shape[0]
    C = _coefficients(P, ts, qdis, g_load, dynamics)
    vnom, omb, beta, r0, a, b, inv_den, dq = C[0], C[1], C[2], C[3], C[4], C[5], C[6], C[7]
    kq = dq * g_load * inv_den  # SOC change per volt of (Vocv − Vtr − R0·Ip) through the load
    kv = kq * vnom
    soc = np.full(m, soc0)
    vtr = np.zeros(m)
    acc = np.zeros(m)
    score = vmeas.shape[0] > 0
    record = traces.shape[0] > 0
    # Without a load the current is the cycler's, so Vt leaves the SOC recursion; writing
    # `ipk + vt * 0.0` would keep the division on the sample-to-sample chain.
    load = g_load != 0.0
    for k in range(ip.shape[0]):
        ipk = ip[k]
        for c in range(m):
            s = soc[c]
            r = s / (omb[c] + beta[c] * s)
            vt = (vnom[c] * r - vtr[c] - r0[c] * ipk) * inv_den[c]
            i = ipk + vt * g_load if load else ipk
            if score:
                e = vt - vmeas[k]
                acc[c] += e * e
            if record:
                traces[0, k] = vt
                traces[1, k] = i
                traces[2, k] = s
                traces[3, k] = vtr[c]
            if load:
                # s − dq·i regrouped: only the division and one subtraction stay on the
                # sample-to-sample chain (≈1.5× faster for one candidate; same value up to rounding)
                soc[c] = (s - dq[c] * ipk + kq[c] * (vtr[c] + r0[c] * ipk)) - kv[c] * r
            else:
                soc[c] = s - i * dq[c]
            vtr[c] = a[c] * vtr[c] + b[c] * i
    out[:] = acc


@nb.njit(cache=True, parallel=True, nogil=True)
def ise_population(P, ip, vmeas, ts, soc0, qdis, g_load, dynamics, n_blocks):
    """Integral square error, eq. 13, of every row of ``P`` against ``vmeas``."""
    m = P.shape[0]
    out = np.empty(m)
    no_traces = np.empty((0, 0))
    size = (m + n_blocks - 1) // n_blocks
    for j in nb.prange(n_blocks):
        lo = j * size
        hi = min(m, lo + size)
        if lo < hi:
            _run_block(P[lo:hi], ip, vmeas, ts, soc0, qdis, g_load, dynamics, out[lo:hi], no_traces)
    return out


@nb.njit(cache=True, nogil=True)
def ise_serial(P, ip, vmeas, ts, soc0, qdis, g_load, dynamics):
    """As :func:`ise_population` on the calling thread only (no thread pool, GIL released)."""
    out = np.empty(P.shape[0])
    _run_block(P, ip, vmeas, ts, soc0, qdis, g_load, dynamics, out, np.empty((0, 0)))
    return out


@nb.njit(cache=True, nogil=True)
def ise_one(x, free, base, fade, ip, vmeas, ts, soc0, qdis, g_load, dynamics):
    """ISE of one candidate ``x`` of free parameters (columns ``free`` of the fresh-cell vector
    ``base``; effective parameters = fresh × ``fade``): the single-candidate path of the local
    searches and RUN. Same value, bit for bit, as :func:`ise_serial` on that one row: the same
    arithmetic in the same order as :func:`_run_block`, with the state kept in scalars (in the
    block kernel it lives in arrays, and for one candidate every sample then waits for a store
    and a reload of SOC and Vtr on the sample-to-sample chain)."""
    P = np.empty((1, base.shape[0]))
    for j in range(base.shape[0]):
        P[0, j] = base[j]
    for j in range(free.shape[0]):
        P[0, free[j]] = x[j]
    for j in range(base.shape[0]):
        P[0, j] = P[0, j] * fade[j]
    C = _coefficients(P, ts, qdis, g_load, dynamics)
    vnom, omb, beta, r0, a, b, inv_den, dq = (
        C[0, 0],
        C[1, 0],
        C[2, 0],
        C[3, 0],
        C[4, 0],
        C[5, 0],
        C[6, 0],
        C[7, 0],
    )
    kq = dq * g_load * inv_den
    kv = kq * vnom
    s = soc0
    vtr = 0.0
    acc = 0.0
    if g_load != 0.0:
        for k in range(ip.shape[0]):
            ipk = ip[k]
            r = s / (omb + beta * s)
            vt = (vnom * r - vtr - r0 * ipk) * inv_den
            i = ipk + vt * g_load
            e = vt - vmeas[k]
            acc += e * e
            s = (s - dq * ipk + kq * (vtr + r0 * ipk)) - kv * r
            vtr = a * vtr + b * i
    else:
        for k in range(ip.shape[0]):
            ipk = ip[k]
            r = s / (omb + beta * s)
            vt = (vnom * r - vtr - r0 * ipk) * inv_den
            e = vt - vmeas[k]
            acc += e * e
            s = s - ipk * dq
            vtr = a * vtr + b * ipk
    return acc


@nb.njit(cache=True)
def simulate_one(p, ip, ts, soc0, qdis, g_load, dynamics):
    """Traces (Vt, I, SOC, Vtr), shape (4, n), of one row ``p`` of effective parameters."""
    traces = np.empty((4, ip.shape[0]))
    out = np.empty(1)
    _run_block(p.reshape(1, -1), ip, np.empty(0), ts, soc0, qdis, g_load, dynamics, out, traces)
    return traces
