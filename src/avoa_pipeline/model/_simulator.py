"""The compiled simulator, WRITTEN BY ``python -m avoa_pipeline.model.loopgen --write``:
do not edit (edit the base in ``model/loopgen.py`` or an element's ``Kernel``).

The elements, in registry order: second_rc, third_rc, soc_resistance, diffusion, hysteresis,
butler_volmer, thermal, ocv_shape, current_offset, voltage_offset, coulombic_efficiency, r0_soc,
r1_soc, r0_charge, bv_arrhenius, thermal_tau, entropic, capacity_temperature.
"""

# fmt: off
# ruff: noqa
import numba as nb
import numpy as np

N_KNOTS = 6  # the vector elements' knots


@nb.njit(cache=True, nogil=True)
def simulate_core(P, table, tab_lo, tab_step, dudt_shape, nk, k_lo, k_step, cur, dt, uniform, dinv_t, two_rt_f, g_load, sel, out, tr):  # noqa: C901
    """Terminal voltage of every physical row of ``P`` at the selected samples (simulate_core: the elements compiled in the core).

    ``table``: the OCV table on a uniform grid (empty: the rational OCV); ``dudt_shape``: the
    shape of its ∂U/∂T over SOC on the same grid, which the entropic coefficient multiplies (empty:
    none, the coefficient alone). ``sel[k]``: the row of
    ``out`` (n_selected, m) that sample k goes to, or −1. ``tr`` (5, n) records SOC, h, the RC
    voltages, the thermal R0 factor and the battery current of row 0 when non-empty (zeros where
    no element writes them). An element whose parameter is neutral in every row is skipped (the
    flags do not change inside the loops, so the compiler takes the branches out of them).

    Long records (issue 25): the voltage is computed only at samples that are returned or traced
    (or under a load, where the current follows it); between them only the state is stepped, and
    across a held current (same current, step and temperature) with the hold's increments computed
    once. Written by ``model/loopgen.py`` from the elements' statements; one function on purpose
    (its docstring says why).
    """
    m = P.shape[0]
    n = cur.shape[0]
    record = tr.shape[0] > 0
    rational = table.shape[0] == 0
    nt = table.shape[0]
    vnom = P[:, 0].copy()
    omb = P[:, 1].copy()
    beta = 1.0 - omb
    q3600 = 3600.0 * P[:, 2]
    soc = P[:, 3].copy()
    r0 = P[:, 4].copy()
    r1 = P[:, 5].copy()
    tau1 = P[:, 6].copy()
    r2 = P[:, 7].copy()
    tau2 = P[:, 8].copy()
    r3 = P[:, 9].copy()
    tau3 = P[:, 10].copy()
    klow = P[:, 11].copy()
    sig = P[:, 12].copy()
    kd = P[:, 13].copy()
    taud = P[:, 14].copy()
    hm = P[:, 15].copy()
    gam = P[:, 16].copy()
    h = P[:, 17].copy()
    bvg = P[:, 18].copy()
    th0 = P[:, 19].copy()
    th1 = P[:, 20].copy()
    d = P[:, 29 : 29 + nk].copy()
    ioff = P[:, 21].copy()
    voff = P[:, 22].copy()
    eta = P[:, 23].copy()
    a1 = np.exp(-dt[0] / tau1)
    v1 = np.zeros(m)
    b1 = np.zeros(m)
    dqs = np.zeros(m)
    a2 = np.exp(-dt[0] / tau2)
    v2 = np.zeros(m)
    b2 = np.zeros(m)
    a3 = np.exp(-dt[0] / tau3)
    v3 = np.zeros(m)
    b3 = np.zeros(m)
    ad = np.exp(-dt[0] / taud)
    dl = np.zeros(m)
    bd = np.zeros(m)
    hx = np.zeros(m)
    hs = np.zeros(m)
    hon = np.zeros(m, dtype=np.bool_)
    rc2 = np.any(r2 != 0.0)
    rc3 = np.any(r3 != 0.0)
    low = np.any(klow != 0.0)
    diff = np.any(kd != 0.0)
    hyst = np.any(hm != 0.0)
    bv = np.any(bvg != 0.0)
    therm0 = np.any(th0 != 0.0)
    therm1 = np.any(th1 != 0.0)
    shape = np.any(d != 0.0)
    load = g_load != 0.0
    # a held current between returned samples: the state's per-sample increments are constants
    # of the hold (no element there depends on the state itself), so they are computed once and
    # the states stepped in tight loops, the same operations in the same order as below
    fast = not load and not record
    tdep = False  # the state's increments depend on the temperature: a hold ends where it moves
    fast = fast and not low
    tdep = tdep or therm1
    k = 0
    while k < n:
        dtk = dt[k]
        ik0 = cur[k]
        # the same current over the same step as the sample before (a cycler's hold; never under
        # a load, whose current follows the voltage): decays of the hold are the same numbers
        held = not load and k > 0 and ik0 == cur[k - 1] and dtk == dt[k - 1]
        dinv = dinv_t[k]
        rtf = two_rt_f[k]
        row = sel[k]
        # an uneven step's decays: made afresh only where the step differs from the last one (a
        # rest merged into one step by ``ecm.simulate_physical``, an uneven logger); the same
        # numbers where it does not
        if not uniform and not (k > 0 and dtk == dt[k - 1]):
            for c in range(m):
                a1[c] = np.exp(-dtk / tau1[c])
                a2[c] = np.exp(-dtk / tau2[c])
                a3[c] = np.exp(-dtk / tau3[c])
                ad[c] = np.exp(-dtk / taud[c])
        dtemp = 0.0  # T − Tref (K), for the elements that read it
        if False:
            tk = rtf * 5802.259060682928
            dtemp = tk - 1.0 / (1.0 / tk - dinv)
        if fast and row < 0:
            e = k + 1
            while (e < n and sel[e] < 0 and cur[e] == ik0 and dt[e] == dtk
                   and (not tdep or dinv_t[e] == dinv)):
                e += 1
            if e - k > 1:
                for c in range(m):
                    ip = ik0
                    ip += ioff[c]
                    i = ip
                    g = 1.0
                    f1 = 1.0
                    if therm1:
                        f1 = np.exp(th1[c] * dinv)
                    gi = f1 * g * i
                    b1[c] = r1[c] * (1.0 - a1[c]) * gi
                    b2[c] = r2[c] * (1.0 - a2[c]) * gi
                    b3[c] = r3[c] * (1.0 - a3[c]) * gi
                    bd[c] = (1.0 - ad[c]) * kd[c] * i
                    ie = i
                    ie = i if i > 0.0 else eta[c] * i
                    dqs[c] = ie * dtk / (q3600[c])
                    hon[c] = hyst and i != 0.0
                    if hon[c]:
                        hx[c] = np.exp(-abs(dqs[c] * gam[c]))
                        hs[c] = (1.0 - hx[c]) * (1.0 if i > 0.0 else -1.0)
                for _ in range(e - k):
                    for c in range(m):
                        v1[c] = a1[c] * v1[c] + b1[c]
                    if rc2:
                        for c in range(m):
                            v2[c] = a2[c] * v2[c] + b2[c]
                    if rc3:
                        for c in range(m):
                            v3[c] = a3[c] * v3[c] + b3[c]
                    if diff:
                        for c in range(m):
                            dl[c] = ad[c] * dl[c] + bd[c]
                    if hyst:
                        for c in range(m):
                            if hon[c]:
                                h[c] = hx[c] * h[c] - hs[c]
                    for c in range(m):
                        soc[c] = soc[c] - dqs[c]
                k = e
                continue
        # the terminal voltage is needed only where it is returned or recorded, or where a load
        # makes the current follow it; elsewhere only the state is stepped (a fit returns a
        # thinned subset of a long record, so most samples only carry the state forward)
        need_v = load or record or row >= 0
        for c in range(m):
            s = soc[c]
            g = 1.0
            f1 = 1.0
            if low:
                g = 1.0 + klow[c] * np.exp(-min(max(s, -0.5), 2.0) / sig[c])
            if therm1:
                f1 = np.exp(th1[c] * dinv)
            ip = ik0
            ip += ioff[c]
            i = ip
            if need_v:
                so = s
                if diff:
                    so = s - dl[c]
                if rational:
                    sc = min(max(so, 0.0), 1.2)  # the rational curve is singular outside
                    e = vnom[c] * sc / (omb[c] + beta[c] * sc)
                else:
                    x = (so - tab_lo) / tab_step
                    if x <= 0.0:
                        e = table[0]
                    elif x >= nt - 1:
                        e = table[nt - 1]
                    else:
                        j = int(x)
                        w = x - j
                        e = (1.0 - w) * table[j] + w * table[j + 1]
                    sc = so
                if shape:
                    x = (sc - k_lo) / k_step
                    if x <= 0.0:
                        e += d[c, 0]
                    elif x >= nk - 1:
                        e += d[c, nk - 1]
                    else:
                        j = int(x)
                        w = x - j
                        e += (1.0 - w) * d[c, j] + w * d[c, j + 1]
                e += voff[c]
                if hyst:
                    e += hm[c] * h[c]
                f0 = 1.0
                if therm0:
                    f0 = np.exp(th0[c] * dinv)
                ro = f0 * g * r0[c]
                e -= v1[c] + v2[c] + v3[c]
                if load:  # the load's current follows the terminal voltage: solved exactly
                    v = (e - ro * ip) / (1.0 + ro * g_load)
                    i = ip + v * g_load
                else:
                    v = e - ro * i
                    if bv:
                        gb = bvg[c]
                        v -= rtf * np.arcsinh(0.5 * gb * i)
                if row >= 0:
                    out[row, c] = v
                if record and c == 0:
                    tr[0, k] = s
                    tr[2, k] = v1[c] + v2[c] + v3[c]
                    tr[3, k] = f0
                    tr[4, k] = i
                    tr[1, k] = h[c]
            gi = f1 * g * i
            v1[c] = a1[c] * v1[c] + r1[c] * (1.0 - a1[c]) * gi
            if rc2:
                v2[c] = a2[c] * v2[c] + r2[c] * (1.0 - a2[c]) * gi
            if rc3:
                v3[c] = a3[c] * v3[c] + r3[c] * (1.0 - a3[c]) * gi
            if diff:
                dl[c] = ad[c] * dl[c] + (1.0 - ad[c]) * kd[c] * i
            ie = i
            ie = i if i > 0.0 else eta[c] * i
            dq = ie * dtk / (q3600[c])
            if hyst and i != 0.0:
                if not held:
                    hx[c] = np.exp(-abs(dq * gam[c]))
                ex = hx[c]
                h[c] = ex * h[c] - (1.0 - ex) * (1.0 if i > 0.0 else -1.0)
            soc[c] = s - dq
        k += 1

@nb.njit(cache=True, nogil=True)
def simulate_extras(P, table, tab_lo, tab_step, dudt_shape, nk, k_lo, k_step, cur, dt, uniform, dinv_t, two_rt_f, g_load, sel, out, tr):  # noqa: C901
    """Terminal voltage of every physical row of ``P`` at the selected samples (simulate_extras: the elements compiled in the core).

    ``table``: the OCV table on a uniform grid (empty: the rational OCV); ``dudt_shape``: the
    shape of its ∂U/∂T over SOC on the same grid, which the entropic coefficient multiplies (empty:
    none, the coefficient alone). ``sel[k]``: the row of
    ``out`` (n_selected, m) that sample k goes to, or −1. ``tr`` (5, n) records SOC, h, the RC
    voltages, the thermal R0 factor and the battery current of row 0 when non-empty (zeros where
    no element writes them). An element whose parameter is neutral in every row is skipped (the
    flags do not change inside the loops, so the compiler takes the branches out of them).

    Long records (issue 25): the voltage is computed only at samples that are returned or traced
    (or under a load, where the current follows it); between them only the state is stepped, and
    across a held current (same current, step and temperature) with the hold's increments computed
    once. Written by ``model/loopgen.py`` from the elements' statements; one function on purpose
    (its docstring says why).
    """
    m = P.shape[0]
    n = cur.shape[0]
    record = tr.shape[0] > 0
    rational = table.shape[0] == 0
    nt = table.shape[0]
    vnom = P[:, 0].copy()
    omb = P[:, 1].copy()
    beta = 1.0 - omb
    q3600 = 3600.0 * P[:, 2]
    soc = P[:, 3].copy()
    r0 = P[:, 4].copy()
    r1 = P[:, 5].copy()
    tau1 = P[:, 6].copy()
    r2 = P[:, 7].copy()
    tau2 = P[:, 8].copy()
    r3 = P[:, 9].copy()
    tau3 = P[:, 10].copy()
    klow = P[:, 11].copy()
    sig = P[:, 12].copy()
    kd = P[:, 13].copy()
    taud = P[:, 14].copy()
    hm = P[:, 15].copy()
    gam = P[:, 16].copy()
    h = P[:, 17].copy()
    bvg = P[:, 18].copy()
    th0 = P[:, 19].copy()
    th1 = P[:, 20].copy()
    d = P[:, 29 : 29 + nk].copy()
    ioff = P[:, 21].copy()
    voff = P[:, 22].copy()
    eta = P[:, 23].copy()
    l0 = P[:, 35 : 35 + nk].copy()
    l1 = P[:, 41 : 41 + nk].copy()
    rho = P[:, 24].copy()
    thbv = P[:, 25].copy()
    thtau = P[:, 26].copy()
    dudt = P[:, 27].copy()
    kq = P[:, 28].copy()
    a1 = np.exp(-dt[0] / tau1)
    v1 = np.zeros(m)
    b1 = np.zeros(m)
    dqs = np.zeros(m)
    a2 = np.exp(-dt[0] / tau2)
    v2 = np.zeros(m)
    b2 = np.zeros(m)
    a3 = np.exp(-dt[0] / tau3)
    v3 = np.zeros(m)
    b3 = np.zeros(m)
    ad = np.exp(-dt[0] / taud)
    dl = np.zeros(m)
    bd = np.zeros(m)
    hx = np.zeros(m)
    hs = np.zeros(m)
    hon = np.zeros(m, dtype=np.bool_)
    rc2 = np.any(r2 != 0.0)
    rc3 = np.any(r3 != 0.0)
    low = np.any(klow != 0.0)
    diff = np.any(kd != 0.0)
    hyst = np.any(hm != 0.0)
    bv = np.any(bvg != 0.0)
    therm0 = np.any(th0 != 0.0)
    therm1 = np.any(th1 != 0.0)
    shape = np.any(d != 0.0)
    soc_r0 = np.any(l0 != 0.0)
    soc_r1 = np.any(l1 != 0.0)
    r0chg = np.any(rho != 0.0)
    bvarr = np.any(thbv != 0.0)
    ttau = np.any(thtau != 0.0)
    entr = np.any(dudt != 0.0)
    qlaw = np.any(kq != 0.0)
    load = g_load != 0.0
    # a held current between returned samples: the state's per-sample increments are constants
    # of the hold (no element there depends on the state itself), so they are computed once and
    # the states stepped in tight loops, the same operations in the same order as below
    fast = not load and not record
    tdep = False  # the state's increments depend on the temperature: a hold ends where it moves
    fast = fast and not low
    tdep = tdep or therm1
    if soc_r1:
        fast = False
    tdep = tdep or ttau
    tdep = tdep or qlaw
    k = 0
    while k < n:
        dtk = dt[k]
        ik0 = cur[k]
        # the same current over the same step as the sample before (a cycler's hold; never under
        # a load, whose current follows the voltage): decays of the hold are the same numbers
        held = not load and k > 0 and ik0 == cur[k - 1] and dtk == dt[k - 1]
        if qlaw and held:
            held = dinv_t[k] == dinv_t[k - 1]
        dinv = dinv_t[k]
        rtf = two_rt_f[k]
        row = sel[k]
        # an uneven step's decays: made afresh only where the step differs from the last one (a
        # rest merged into one step by ``ecm.simulate_physical``, an uneven logger); the same
        # numbers where it does not
        if not uniform and not (k > 0 and dtk == dt[k - 1]):
            for c in range(m):
                a1[c] = np.exp(-dtk / tau1[c])
                a2[c] = np.exp(-dtk / tau2[c])
                a3[c] = np.exp(-dtk / tau3[c])
                ad[c] = np.exp(-dtk / taud[c])
        dtemp = 0.0  # T − Tref (K), for the elements that read it
        if ttau:
            for c in range(m):
                ft = np.exp(thtau[c] * dinv)
                a1[c] = np.exp(-dtk / (tau1[c] * ft))
                a2[c] = np.exp(-dtk / (tau2[c] * ft))
                a3[c] = np.exp(-dtk / (tau3[c] * ft))
        if entr or qlaw:
            tk = rtf * 5802.259060682928
            dtemp = tk - 1.0 / (1.0 / tk - dinv)
        if fast and row < 0:
            e = k + 1
            while (e < n and sel[e] < 0 and cur[e] == ik0 and dt[e] == dtk
                   and (not tdep or dinv_t[e] == dinv)):
                e += 1
            if e - k > 1:
                for c in range(m):
                    ip = ik0
                    ip += ioff[c]
                    i = ip
                    g = 1.0
                    f1 = 1.0
                    if therm1:
                        f1 = np.exp(th1[c] * dinv)
                    gi = f1 * g * i
                    b1[c] = r1[c] * (1.0 - a1[c]) * gi
                    b2[c] = r2[c] * (1.0 - a2[c]) * gi
                    b3[c] = r3[c] * (1.0 - a3[c]) * gi
                    bd[c] = (1.0 - ad[c]) * kd[c] * i
                    ie = i
                    ie = i if i > 0.0 else eta[c] * i
                    qf = 1.0 + kq[c] * dtemp if qlaw else 1.0
                    dqs[c] = ie * dtk / (q3600[c] * qf)
                    hon[c] = hyst and i != 0.0
                    if hon[c]:
                        hx[c] = np.exp(-abs(dqs[c] * gam[c]))
                        hs[c] = (1.0 - hx[c]) * (1.0 if i > 0.0 else -1.0)
                for _ in range(e - k):
                    for c in range(m):
                        v1[c] = a1[c] * v1[c] + b1[c]
                    if rc2:
                        for c in range(m):
                            v2[c] = a2[c] * v2[c] + b2[c]
                    if rc3:
                        for c in range(m):
                            v3[c] = a3[c] * v3[c] + b3[c]
                    if diff:
                        for c in range(m):
                            dl[c] = ad[c] * dl[c] + bd[c]
                    if hyst:
                        for c in range(m):
                            if hon[c]:
                                h[c] = hx[c] * h[c] - hs[c]
                    for c in range(m):
                        soc[c] = soc[c] - dqs[c]
                k = e
                continue
        # the terminal voltage is needed only where it is returned or recorded, or where a load
        # makes the current follow it; elsewhere only the state is stepped (a fit returns a
        # thinned subset of a long record, so most samples only carry the state forward)
        need_v = load or record or row >= 0
        for c in range(m):
            s = soc[c]
            g = 1.0
            f1 = 1.0
            if low:
                g = 1.0 + klow[c] * np.exp(-min(max(s, -0.5), 2.0) / sig[c])
            if therm1:
                f1 = np.exp(th1[c] * dinv)
            g1 = 1.0
            if soc_r1:
                xs = (s - k_lo) / k_step
                js = min(max(int(xs), 0), nk - 2) if xs > 0.0 else 0
                ws = min(max(xs - js, 0.0), 1.0)
                g1 = np.exp((1.0 - ws) * l1[c, js] + ws * l1[c, js + 1])
            ip = ik0
            ip += ioff[c]
            i = ip
            if need_v:
                so = s
                if diff:
                    so = s - dl[c]
                if rational:
                    sc = min(max(so, 0.0), 1.2)  # the rational curve is singular outside
                    e = vnom[c] * sc / (omb[c] + beta[c] * sc)
                else:
                    x = (so - tab_lo) / tab_step
                    if x <= 0.0:
                        e = table[0]
                    elif x >= nt - 1:
                        e = table[nt - 1]
                    else:
                        j = int(x)
                        w = x - j
                        e = (1.0 - w) * table[j] + w * table[j + 1]
                    sc = so
                if shape:
                    x = (sc - k_lo) / k_step
                    if x <= 0.0:
                        e += d[c, 0]
                    elif x >= nk - 1:
                        e += d[c, nk - 1]
                    else:
                        j = int(x)
                        w = x - j
                        e += (1.0 - w) * d[c, j] + w * d[c, j + 1]
                e += voff[c]
                if entr:
                    pf = 1.0  # the profile's shape at the SOC the OCV was read at; 1 without a profile
                    if dudt_shape.shape[0] > 0:
                        xp = (sc - tab_lo) / tab_step
                        if xp <= 0.0:
                            pf = dudt_shape[0]
                        elif xp >= dudt_shape.shape[0] - 1:
                            pf = dudt_shape[dudt_shape.shape[0] - 1]
                        else:
                            jp = int(xp)
                            pf = (1.0 - (xp - jp)) * dudt_shape[jp] + (xp - jp) * dudt_shape[jp + 1]
                    e += dudt[c] * pf * dtemp
                if hyst:
                    e += hm[c] * h[c]
                f0 = 1.0
                if therm0:
                    f0 = np.exp(th0[c] * dinv)
                ro = f0 * g * r0[c]
                if soc_r0:  # log-multipliers at the knots, by the (bulk) SOC
                    xs = (s - k_lo) / k_step
                    js = min(max(int(xs), 0), nk - 2) if xs > 0.0 else 0
                    ws = min(max(xs - js, 0.0), 1.0)
                    ro *= np.exp((1.0 - ws) * l0[c, js] + ws * l0[c, js + 1])
                if r0chg and ip < 0.0:
                    ro *= np.exp(rho[c])
                e -= v1[c] + v2[c] + v3[c]
                if load:  # the load's current follows the terminal voltage: solved exactly
                    v = (e - ro * ip) / (1.0 + ro * g_load)
                    i = ip + v * g_load
                else:
                    v = e - ro * i
                    if bv:
                        gb = bvg[c]
                        if bvarr:
                            gb *= np.exp(thbv[c] * dinv)
                        v -= rtf * np.arcsinh(0.5 * gb * i)
                if row >= 0:
                    out[row, c] = v
                if record and c == 0:
                    tr[0, k] = s
                    tr[2, k] = v1[c] + v2[c] + v3[c]
                    tr[3, k] = f0
                    tr[4, k] = i
                    tr[1, k] = h[c]
            gi = f1 * g * i
            v1[c] = a1[c] * v1[c] + r1[c] * g1 * (1.0 - a1[c]) * gi
            if rc2:
                v2[c] = a2[c] * v2[c] + r2[c] * (1.0 - a2[c]) * gi
            if rc3:
                v3[c] = a3[c] * v3[c] + r3[c] * (1.0 - a3[c]) * gi
            if diff:
                dl[c] = ad[c] * dl[c] + (1.0 - ad[c]) * kd[c] * i
            ie = i
            ie = i if i > 0.0 else eta[c] * i
            qf = 1.0 + kq[c] * dtemp if qlaw else 1.0
            dq = ie * dtk / (q3600[c] * qf)
            if hyst and i != 0.0:
                if not held:
                    hx[c] = np.exp(-abs(dq * gam[c]))
                ex = hx[c]
                h[c] = ex * h[c] - (1.0 - ex) * (1.0 if i > 0.0 else -1.0)
            soc[c] = s - dq
        k += 1

@nb.njit(cache=True, nogil=True)
def step(P, table, tab_lo, tab_step, dudt_shape, nk, k_lo, k_step, grid, i_read, dtk, dinv, rtf, X, bias, need_v, update, ext, out):  # noqa: C901
    """One sample of the SOC filter's state-space model for every row (``estimate.Model``).

    ``X`` (m, states): the states of ``loopgen.states``, in that order (:data:`STATES`), stepped
    in place when ``update``; ``out`` (m,): the terminal voltage before the step when ``need_v``.
    Written by ``model/loopgen.py`` from the elements' statements, the same as the simulator's.
    """
    m = P.shape[0]
    rational = table.shape[0] == 0
    dt = np.full(1, dtk)  # what the setup reads as the first step
    vnom = P[:, 0].copy()
    omb = P[:, 1].copy()
    beta = 1.0 - omb
    q3600 = 3600.0 * P[:, 2]
    r0 = P[:, 4].copy()
    r1 = P[:, 5].copy()
    tau1 = P[:, 6].copy()
    r2 = P[:, 7].copy()
    tau2 = P[:, 8].copy()
    r3 = P[:, 9].copy()
    tau3 = P[:, 10].copy()
    klow = P[:, 11].copy()
    sig = P[:, 12].copy()
    kd = P[:, 13].copy()
    taud = P[:, 14].copy()
    hm = P[:, 15].copy()
    gam = P[:, 16].copy()
    h = P[:, 17].copy()
    bvg = P[:, 18].copy()
    th0 = P[:, 19].copy()
    th1 = P[:, 20].copy()
    d = P[:, 29 : 29 + nk].copy()
    ioff = P[:, 21].copy()
    voff = P[:, 22].copy()
    eta = P[:, 23].copy()
    l0 = P[:, 35 : 35 + nk].copy()
    l1 = P[:, 41 : 41 + nk].copy()
    rho = P[:, 24].copy()
    thbv = P[:, 25].copy()
    thtau = P[:, 26].copy()
    dudt = P[:, 27].copy()
    kq = P[:, 28].copy()
    a1 = np.exp(-dt[0] / tau1)
    a2 = np.exp(-dt[0] / tau2)
    v2 = np.zeros(m)
    b2 = np.zeros(m)
    a3 = np.exp(-dt[0] / tau3)
    v3 = np.zeros(m)
    b3 = np.zeros(m)
    ad = np.exp(-dt[0] / taud)
    dl = np.zeros(m)
    bd = np.zeros(m)
    hx = np.zeros(m)
    hs = np.zeros(m)
    hon = np.zeros(m, dtype=np.bool_)
    rc2 = np.any(r2 != 0.0)
    rc3 = np.any(r3 != 0.0)
    low = np.any(klow != 0.0)
    diff = np.any(kd != 0.0)
    hyst = np.any(hm != 0.0)
    bv = np.any(bvg != 0.0)
    therm0 = np.any(th0 != 0.0)
    therm1 = np.any(th1 != 0.0)
    shape = np.any(d != 0.0)
    soc_r0 = np.any(l0 != 0.0)
    soc_r1 = np.any(l1 != 0.0)
    r0chg = np.any(rho != 0.0)
    bvarr = np.any(thbv != 0.0)
    ttau = np.any(thtau != 0.0)
    entr = np.any(dudt != 0.0)
    qlaw = np.any(kq != 0.0)
    soc = X[:, 0].copy()
    v1 = X[:, 1].copy()
    v2 = X[:, 2].copy()
    v3 = X[:, 3].copy()
    dl = X[:, 4].copy()
    h = X[:, 5].copy()
    held = False  # the hysteresis decay is computed afresh
    dtemp = 0.0  # T − Tref (K), for the elements that read it
    if ttau:
        for c in range(m):
            ft = np.exp(thtau[c] * dinv)
            a1[c] = np.exp(-dtk / (tau1[c] * ft))
            a2[c] = np.exp(-dtk / (tau2[c] * ft))
            a3[c] = np.exp(-dtk / (tau3[c] * ft))
    if entr or qlaw:
        tk = rtf * 5802.259060682928
        dtemp = tk - 1.0 / (1.0 / tk - dinv)
    for c in range(m):
        s = soc[c]
        g = 1.0
        f1 = 1.0
        if low:
            g = 1.0 + klow[c] * np.exp(-min(max(s, -0.5), 2.0) / sig[c])
        if therm1:
            f1 = np.exp(th1[c] * dinv)
        g1 = 1.0
        if soc_r1:
            xs = (s - k_lo) / k_step
            js = min(max(int(xs), 0), nk - 2) if xs > 0.0 else 0
            ws = min(max(xs - js, 0.0), 1.0)
            g1 = np.exp((1.0 - ws) * l1[c, js] + ws * l1[c, js + 1])
        ip = i_read
        ip += ioff[c]
        ip += bias[c]  # the filter's current-sensor bias state
        i = ip
        if need_v:
            so = s
            if diff:
                so = s - dl[c]
            if rational:
                sc = min(max(so, 0.0), 1.2)  # the rational curve is singular outside
                e = vnom[c] * sc / (omb[c] + beta[c] * sc)
            else:
                e = np.interp(so, grid, table)
                if ext[0] != 0.0:  # the filter's table goes on past its ends with their slopes
                    above = (so - ext[2]) * ext[4] if so > ext[2] else 0.0
                    below = (so - ext[1]) * ext[3] if so < ext[1] else 0.0
                    e = e + (above + below)
                sc = so
            if shape:
                x = (sc - k_lo) / k_step
                if x <= 0.0:
                    e += d[c, 0]
                elif x >= nk - 1:
                    e += d[c, nk - 1]
                else:
                    j = int(x)
                    w = x - j
                    e += (1.0 - w) * d[c, j] + w * d[c, j + 1]
            e += voff[c]
            if entr:
                pf = 1.0  # the profile's shape at the SOC the OCV was read at; 1 without a profile
                if dudt_shape.shape[0] > 0:
                    xp = (sc - tab_lo) / tab_step
                    if xp <= 0.0:
                        pf = dudt_shape[0]
                    elif xp >= dudt_shape.shape[0] - 1:
                        pf = dudt_shape[dudt_shape.shape[0] - 1]
                    else:
                        jp = int(xp)
                        pf = (1.0 - (xp - jp)) * dudt_shape[jp] + (xp - jp) * dudt_shape[jp + 1]
                e += dudt[c] * pf * dtemp
            if hyst:
                e += hm[c] * h[c]
            f0 = 1.0
            if therm0:
                f0 = np.exp(th0[c] * dinv)
            ro = f0 * g * r0[c]
            if soc_r0:  # log-multipliers at the knots, by the (bulk) SOC
                xs = (s - k_lo) / k_step
                js = min(max(int(xs), 0), nk - 2) if xs > 0.0 else 0
                ws = min(max(xs - js, 0.0), 1.0)
                ro *= np.exp((1.0 - ws) * l0[c, js] + ws * l0[c, js + 1])
            if r0chg and ip < 0.0:
                ro *= np.exp(rho[c])
            e -= v1[c]
            e -= v2[c]
            e -= v3[c]
            v = e - ro * i
            if bv:
                gb = bvg[c]
                if bvarr:
                    gb *= np.exp(thbv[c] * dinv)
                v -= rtf * np.arcsinh(0.5 * gb * i)
            out[c] = v
        if update:
            gi = f1 * g * i
            v1[c] = a1[c] * v1[c] + r1[c] * g1 * (1.0 - a1[c]) * gi
            if rc2:
                v2[c] = a2[c] * v2[c] + r2[c] * (1.0 - a2[c]) * gi
            if rc3:
                v3[c] = a3[c] * v3[c] + r3[c] * (1.0 - a3[c]) * gi
            if diff:
                dl[c] = ad[c] * dl[c] + (1.0 - ad[c]) * kd[c] * i
            ie = i
            ie = i if i > 0.0 else eta[c] * i
            qf = 1.0 + kq[c] * dtemp if qlaw else 1.0
            dq = ie * dtk / (q3600[c] * qf)
            if hyst and i != 0.0:
                if not held:
                    hx[c] = np.exp(-abs(dq * gam[c]))
                ex = hx[c]
                h[c] = ex * h[c] - (1.0 - ex) * (1.0 if i > 0.0 else -1.0)
            soc[c] = s - dq
    if update:
        X[:, 0] = soc
        X[:, 1] = v1
        X[:, 2] = v2
        X[:, 3] = v3
        X[:, 4] = dl
        X[:, 5] = h

SIMULATE = {False: simulate_core, True: simulate_extras}
STATES = ("soc", "v1", "v2", "v3", "delta", "h",)  # the columns of step's X
