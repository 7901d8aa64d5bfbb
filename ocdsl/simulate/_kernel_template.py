# Integrator kernel template. NOT imported directly: ocdsl.simulate.compile appends this
# text to a generated module that defines ``rhs(s, y, u, p, out)`` (the model's compiled
# right-hand side) and the Dormand-Prince 8(5,3) tables A, B, C, D, E3, E5 and imports
# math, numpy as np, numba.njit/prange. Keeping the kernel in the same file as the RHS
# lets Numba cache it on disk (a plain global call, no first-class function arguments).
# flake8: noqa

# control kinds
K_CONST = 0     # u = cd[ptr]
K_FOURIER = 1   # half-range Fourier on [0, T]: a0/2 + sum a_n cos(n pi t/T) + b_n sin(n pi t/T)
K_POLY = 2      # sum c_k (t/T)^k
K_TABLE = 3     # piecewise linear: times cd[ptr:ptr+n], values cd[ptr+n:ptr+2n]

N_STAGES = 12


@njit(cache=True, fastmath=False)
def control(t, ck, cp, co, cd, T, u):
    for j in range(ck.shape[0]):
        kind = ck[j]
        ptr = cp[j]
        n = co[j]
        if kind == K_CONST:
            u[j] = cd[ptr]
        elif kind == K_FOURIER:
            w = math.pi * t / T
            c1 = math.cos(w)
            s1 = math.sin(w)
            cn = 1.0
            sn = 0.0
            acc = 0.5 * cd[ptr]
            for k in range(1, n + 1):
                cn, sn = cn * c1 - sn * s1, sn * c1 + cn * s1
                acc += cd[ptr + k] * cn + cd[ptr + n + k] * sn
            u[j] = acc
        elif kind == K_POLY:
            tau = t / T
            acc = 0.0
            for k in range(n, -1, -1):
                acc = acc * tau + cd[ptr + k]
            u[j] = acc
        else:
            if t <= cd[ptr]:
                u[j] = cd[ptr + n]
            elif t >= cd[ptr + n - 1]:
                u[j] = cd[ptr + 2 * n - 1]
            else:
                lo = 0
                hi = n - 1
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    if cd[ptr + mid] <= t:
                        lo = mid
                    else:
                        hi = mid
                t0 = cd[ptr + lo]
                t1 = cd[ptr + hi]
                a = (t - t0) / (t1 - t0)
                u[j] = (1 - a) * cd[ptr + n + lo] + a * cd[ptr + n + hi]


@njit(cache=True)
def deriv(s, y, p, ck, cp, co, cd, T, clock, u, out):
    tc = y[clock] if clock >= 0 else s
    control(tc, ck, cp, co, cd, T, u)
    rhs(s, y, u, p, out)


@njit(cache=True)
def _rms(v, scale):
    acc = 0.0
    for i in range(v.shape[0]):
        q = v[i] / scale[i]
        acc += q * q
    return math.sqrt(acc / v.shape[0])


@njit(cache=True)
def _dense_eval(F, y_old, x, out):
    n = y_old.shape[0]
    for i in range(n):
        acc = 0.0
        for r in range(6, -1, -1):
            acc += F[r, i]
            if (6 - r) % 2 == 0:
                acc *= x
            else:
                acc *= 1.0 - x
        out[i] = acc + y_old[i]


@njit(cache=True)
def _dense_prepare(K, s_old, y_old, y_new, f_new, h, p, ck, cp, co, cd, T, clock, u, ytmp, F):
    # three extra stages, then the 7 interpolation rows (Hairer's DOP853 dense output)
    n = y_old.shape[0]
    for st in range(N_STAGES + 1, N_STAGES + 4):
        for i in range(n):
            acc = 0.0
            for q in range(st):
                acc += A[st, q] * K[q, i]
            ytmp[i] = y_old[i] + h * acc
        deriv(s_old + C[st] * h, ytmp, p, ck, cp, co, cd, T, clock, u, K[st])
    for i in range(n):
        dy = y_new[i] - y_old[i]
        F[0, i] = dy
        F[1, i] = h * K[0, i] - dy
        F[2, i] = 2.0 * dy - h * (f_new[i] + K[0, i])
        for r in range(4):
            acc = 0.0
            for q in range(N_STAGES + 4):
                acc += D[r, q] * K[q, i]
            F[3 + r, i] = h * acc


@njit(cache=True)
def _rk_step(s, y, f, h, p, ck, cp, co, cd, T, clock, u, K, ytmp, y_new, f_new):
    n = y.shape[0]
    for i in range(n):
        K[0, i] = f[i]
    for st in range(1, N_STAGES):
        for i in range(n):
            acc = 0.0
            for q in range(st):
                acc += A[st, q] * K[q, i]
            ytmp[i] = y[i] + h * acc
        deriv(s + C[st] * h, ytmp, p, ck, cp, co, cd, T, clock, u, K[st])
    for i in range(n):
        acc = 0.0
        for q in range(N_STAGES):
            acc += B[q] * K[q, i]
        y_new[i] = y[i] + h * acc
    deriv(s + h, y_new, p, ck, cp, co, cd, T, clock, u, f_new)
    for i in range(n):
        K[N_STAGES, i] = f_new[i]


@njit(cache=True)
def _err_norm(K, h, scale):
    n = scale.shape[0]
    e5 = 0.0
    e3 = 0.0
    for i in range(n):
        a5 = 0.0
        a3 = 0.0
        for q in range(N_STAGES + 1):
            a5 += E5[q] * K[q, i]
            a3 += E3[q] * K[q, i]
        a5 /= scale[i]
        a3 /= scale[i]
        e5 += a5 * a5
        e3 += a3 * a3
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)


@njit(cache=True)
def _grow(arr, need):
    if need <= arr.shape[0]:
        return arr
    m = max(need, 2 * arr.shape[0])
    new = np.empty((m, arr.shape[1]))
    new[:arr.shape[0]] = arr
    return new


@njit(cache=True)
def integrate(y0, s0, s_end, p, ck, cp, co, cd, T, clock, t_stop, rtol, atol, h0,
              max_steps, ev_idx, ev_val, ev_dir, ev_term, n_dense, record):
    """Adaptive DOP853 from s0 to s_end (or until the clock state reaches t_stop).

    Returns (status, s, y, n_steps, n_fev, traj, events): status 0 reached the end,
    1 clock reached t_stop, 2 terminal event, -1 too many steps, -2 step size underflow / non-finite state.
    ``traj`` rows are [s, y...] at each accepted step (and ``n_dense`` dense points in
    between) when ``record``; ``events`` rows are [event index, s, y...].
    """
    n = y0.shape[0]
    nu = ck.shape[0]
    u = np.empty(max(nu, 1))
    K = np.empty((N_STAGES + 4, n))
    F = np.empty((7, n))
    y = y0.copy()
    f = np.empty(n)
    ytmp = np.empty(n)
    y_new = np.empty(n)
    f_new = np.empty(n)
    scale = np.empty(n)
    yd = np.empty(n)
    nev = ev_idx.shape[0]
    traj = np.empty((1024 if record else 0, n + 1))
    ntraj = 0
    events = np.empty((8 if nev > 0 else 0, n + 2))
    nevents = 0
    s = s0
    direction = 1.0 if s_end >= s0 else -1.0
    deriv(s, y, p, ck, cp, co, cd, T, clock, u, f)
    nfev = 1
    if record:
        traj[0, 0] = s
        traj[0, 1:] = y
        ntraj = 1
    use_stop = clock >= 0 and math.isfinite(t_stop)
    # initial step (Hairer, Norsett & Wanner II.4)
    for i in range(n):
        scale[i] = atol[i] + abs(y[i]) * rtol
    if h0 > 0:
        h_abs = h0
    else:
        d0 = _rms(y, scale)
        d1 = _rms(f, scale)
        hh = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
        hh = min(hh, abs(s_end - s0))
        for i in range(n):
            ytmp[i] = y[i] + direction * hh * f[i]
        deriv(s + direction * hh, ytmp, p, ck, cp, co, cd, T, clock, u, f_new)
        nfev += 1
        for i in range(n):
            yd[i] = f_new[i] - f[i]
        d2 = _rms(yd, scale) / hh
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, hh * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
        h_abs = min(100 * hh, h1)
    nsteps = 0
    status = 0
    while True:
        if direction * (s - s_end) >= 0:
            status = 0
            break
        if nsteps >= max_steps:
            status = -1
            break
        min_step = 10.0 * abs(np.nextafter(s, direction * np.inf) - s)
        if h_abs < min_step:
            h_abs = min_step
        rejected = False
        while True:
            h = h_abs * direction
            s_new = s + h
            if direction * (s_new - s_end) > 0:
                s_new = s_end
            h = s_new - s
            h_abs = abs(h)
            _rk_step(s, y, f, h, p, ck, cp, co, cd, T, clock, u, K, ytmp, y_new, f_new)
            nfev += N_STAGES
            finite = True
            for i in range(n):
                scale[i] = atol[i] + max(abs(y[i]), abs(y_new[i])) * rtol
                if not math.isfinite(y_new[i]):
                    finite = False
            err = _err_norm(K, h, scale) if finite else 1e10
            if err < 1.0:
                if err == 0.0:
                    factor = 10.0
                else:
                    factor = min(10.0, 0.9 * err ** (-1.0 / 8.0))
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            h_abs *= max(0.2, 0.9 * err ** (-1.0 / 8.0))
            rejected = True
            if h_abs < min_step:
                break
        if h_abs < min_step and err >= 1.0:
            status = -2
            break
        nsteps += 1
        need_dense = (record and n_dense > 0) or nev > 0
        stop_here = use_stop and direction * (y_new[clock] - t_stop) >= 0
        if need_dense or stop_here:
            _dense_prepare(K, s, y, y_new, f_new, h, p, ck, cp, co, cd, T, clock, u, ytmp, F)
            nfev += 3
        x_end = 1.0
        terminal = False
        if stop_here:
            # clock event: find x with y_clock(x) = t_stop on the dense polynomial
            lo = 0.0
            hi = 1.0
            g_lo = y[clock] - t_stop
            for it in range(60):
                mid = 0.5 * (lo + hi)
                _dense_eval(F, y, mid, yd)
                g = yd[clock] - t_stop
                if (g < 0) == (g_lo < 0):
                    lo = mid
                    g_lo = g
                else:
                    hi = mid
                if hi - lo < 1e-15:
                    break
            x_end = hi
        if nev > 0:
            for e in range(nev):
                ga = y[ev_idx[e]] - ev_val[e]
                gb = y_new[ev_idx[e]] - ev_val[e]
                crosses = (ga < 0 and gb >= 0 and ev_dir[e] >= 0) or (ga > 0 and gb <= 0 and ev_dir[e] <= 0)
                if not crosses:
                    continue
                lo = 0.0
                hi = 1.0
                g_lo = ga
                for it in range(80):
                    mid = 0.5 * (lo + hi)
                    _dense_eval(F, y, mid, yd)
                    g = yd[ev_idx[e]] - ev_val[e]
                    if (g < 0) == (g_lo < 0) and g != 0:
                        lo = mid
                        g_lo = g
                    else:
                        hi = mid
                    if hi - lo < 1e-15:
                        break
                xe = 0.5 * (lo + hi)
                if xe > x_end:
                    continue
                _dense_eval(F, y, xe, yd)
                events = _grow(events, nevents + 1)
                events[nevents, 0] = e
                events[nevents, 1] = s + xe * h
                events[nevents, 2:] = yd
                nevents += 1
                if ev_term[e] != 0:
                    terminal = True
                    x_end = min(x_end, xe)
        if record and n_dense > 0:
            traj = _grow(traj, ntraj + n_dense + 1)
            for k in range(1, n_dense + 1):
                xk = k / (n_dense + 1.0)
                if xk >= x_end:
                    break
                _dense_eval(F, y, xk, yd)
                traj[ntraj, 0] = s + xk * h
                traj[ntraj, 1:] = yd
                ntraj += 1
        if x_end < 1.0:
            # land exactly: a true RK step of the shortened size from the step start
            h2 = x_end * h
            _rk_step(s, y, f, h2, p, ck, cp, co, cd, T, clock, u, K, ytmp, y_new, f_new)
            nfev += N_STAGES
            s_new = s + h2
            if stop_here and not terminal:
                # first-order correction of the tiny clock residual (dense-root error)
                rate = f_new[clock]
                if rate != 0.0:
                    ds = (t_stop - y_new[clock]) / rate
                    for i in range(n):
                        y_new[i] += f_new[i] * ds
                    s_new += ds
        s = s_new
        for i in range(n):
            y[i] = y_new[i]
            f[i] = f_new[i]
        if record:
            traj = _grow(traj, ntraj + 1)
            traj[ntraj, 0] = s
            traj[ntraj, 1:] = y
            ntraj += 1
        if x_end < 1.0 or stop_here:
            status = 2 if terminal else 1
            break
    return status, s, y, nsteps, nfev, traj[:ntraj], events[:nevents]


@njit(cache=True, nogil=True)
def final_batch(Y0, S_end, P, ck, cp, co, CD, Tc, clock, t_stop, rtol, atol, max_steps,
                ev_i, ev_v, ev_d, ev_t, Yf, status, nsteps, n_dense, record):
    """Final states of many runs (rows of Y0, P, CD; per-run S_end, Tc, t_stop). ``n_dense``
    and ``record`` (0 and False) are arguments, not literals: a literal is another type to
    Numba, and ``integrate`` would be compiled once for these calls and again for Python's."""
    for b in range(Y0.shape[0]):
        st, s, y, ns, nf, tr, evs = integrate(Y0[b], 0.0, S_end[b], P[b], ck, cp, co, CD[b],
                                              Tc[b], clock, t_stop[b], rtol, atol, 0.0,
                                              max_steps, ev_i, ev_v, ev_d, ev_t, n_dense, record)
        Yf[b] = y
        status[b] = st
        nsteps[b] = ns
