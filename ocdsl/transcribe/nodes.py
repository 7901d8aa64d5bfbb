"""Pseudospectral nodes, quadrature weights and differentiation matrices (pure NumPy).

Notation. One mesh segment is mapped to tau in [-1, 1] (t = t_a + (tau + 1) h / 2). In a
segment the state is the polynomial of degree ``m - 1`` that interpolates the unknowns
X_0..X_{m-1} at the ``m`` *support* points; the dynamics are imposed at the ``n`` *collocation*
points. With ``D`` the (n, m) matrix mapping support values to d/dtau at the collocation
points, the collocation equations read ``D @ X = (h / 2) * F(X[colloc_in_support], U)``.

Schemes (``n`` = degree = number of collocation points per segment, ``m`` = support size):

- ``LG``: colloc = the n Gauss points (all interior); support = [-1, colloc], m = n + 1;
  the end state is not a support value: x(+1) = x(-1) + weights @ (D @ X).
- ``LGR`` (default Radau, Radau IIA, L-stable): colloc = the n flipped Radau points, the last
  being +1; support = [-1, colloc], m = n + 1; x(+1) = X[-1].
- ``LGR-start`` (GPOPS-II's Radau points, first = -1; not A-stable, so offered under its own
  name for comparison with published GPOPS-II results): support = [colloc, +1], m = n + 1.
- ``LGL``: colloc = support = the n Lobatto points, both ends included, m = n.

Quadrature on the collocation points is exact for polynomials of degree 2n-1 (LG),
2n-2 (LGR, LGR-start) and 2n-3 (LGL).

Nodes are eigenvalues of the Jacobi matrix of the matching Gauss-Jacobi rule (Golub-Welsch),
polished by Newton's method on the Legendre three-term recurrence; interpolation and
differentiation use the barycentric formulas, which stay accurate for several dozen nodes.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

__all__ = [
    "SCHEME_NAMES",
    "Scheme",
    "scheme",
    "lagrange_matrix",
    "differentiation_matrix",
    "legendre_gauss",
    "legendre_gauss_radau",
    "legendre_gauss_lobatto",
]

SCHEME_NAMES = ("LG", "LGR", "LGR-start", "LGL")


# eq=False: fields are arrays, so generated __eq__/__hash__ would fail; instances come from a
# cache, so identity is the meaningful equality and they stay usable as dict keys.
@dataclass(frozen=True, eq=False)
class Scheme:
    """Nodes and matrices of one collocation scheme on the reference segment [-1, 1].

    All arrays are read-only because instances are shared through ``scheme``'s cache.
    """

    name: str  # "LG", "LGR", "LGR-start" or "LGL"
    degree: int  # n = number of collocation points per segment
    support: np.ndarray  # (m,) ascending, support[0] == -1: where a segment's state unknowns live
    colloc: np.ndarray  # (n,) ascending collocation points
    D: np.ndarray  # (n, m): d/dtau of the interpolant through `support`, at `colloc`
    weights: np.ndarray  # (n,) quadrature weights at `colloc`, sum 2
    end_from_support: bool  # support[-1] == +1; else x(+1) = x(-1) + weights @ (D @ X)
    colloc_in_support: np.ndarray  # (n,) int: colloc[i] == support[k] with k = this[i], or -1


# ----------------------------------------------------------------------------------------
# Legendre polynomials and Gauss-type rules
# ----------------------------------------------------------------------------------------

def _legendre(n: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """P_k, P_k', P_k'' at x for k = 0..n, each of shape (n + 1, len(x)).

    The derivative recurrence P'_{k+1} = P'_{k-1} + (2k+1) P_k is used rather than the
    closed form with 1/(1 - x^2) because it stays finite at x = +-1.
    """
    x = np.asarray(x, dtype=float)
    P = np.zeros((n + 1,) + x.shape)
    dP = np.zeros_like(P)
    d2P = np.zeros_like(P)
    P[0] = 1.0
    if n >= 1:
        P[1] = x
        dP[1] = 1.0
    for k in range(1, n):
        P[k + 1] = ((2 * k + 1) * x * P[k] - k * P[k - 1]) / (k + 1)
        dP[k + 1] = dP[k - 1] + (2 * k + 1) * P[k]
        d2P[k + 1] = d2P[k - 1] + (2 * k + 1) * dP[k]
    return P, dP, d2P


def _jacobi_roots(m: int, a: float, b: float) -> np.ndarray:
    """Roots of the degree-m Jacobi polynomial P_m^(a,b), weight (1-x)^a (1+x)^b (Golub-Welsch).

    Only a starting guess (accurate to a few ulps times the condition of the eigenproblem);
    callers polish it with Newton on the Legendre form of the same polynomial.
    """
    if m == 0:
        return np.zeros(0)
    k = np.arange(m, dtype=float)
    s = 2 * k + a + b
    if a == b:
        diag = np.zeros(m)  # the general formula is 0/0 at k = 0 when a = b = 0
    else:
        diag = (b * b - a * a) / (s * (s + 2))
    k = np.arange(1, m, dtype=float)
    s = 2 * k + a + b
    off = np.sqrt(4 * k * (k + a) * (k + b) * (k + a + b) / (s * s * (s + 1) * (s - 1)))
    J = np.diag(diag) + np.diag(off, 1) + np.diag(off, -1)
    return np.sort(np.linalg.eigvalsh(J))


def _newton(x: np.ndarray, f_and_df) -> np.ndarray:
    """Polish simple roots; the eigenvalue guesses are close, so a few steps reach 1 ulp."""
    x = x.copy()
    for _ in range(20):
        f, df = f_and_df(x)
        step = f / df
        x -= step
        if np.max(np.abs(step), initial=0.0) <= 1e-16:
            break
    return x


def _check_n(n, least: int, what: str) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise ValueError(f"{what}: the number of points must be an integer, got {n!r}")
    if n < least:
        raise ValueError(f"{what}: needs at least {least} point(s), got {n}")
    return int(n)


def _copies(rule):
    """``rule`` memoised by its arguments; each call returns fresh copies of the arrays. The
    mesh refinement asks for the same few rules hundreds of times per run (Goddard: 496
    Lobatto rules, 0.15 s of eigenvalue problems and Newton polishing)."""
    cached = functools.lru_cache(maxsize=None)(rule)

    @functools.wraps(rule)
    def fresh(*args, **kwargs):
        # a bool hashes as 0/1 and is refused by the rule itself: never served from the cache
        plain = all(isinstance(a, (int, np.integer, str)) and not isinstance(a, bool)
                    for a in (*args, *kwargs.values()))
        x, w = (cached if plain else rule)(*args, **kwargs)
        return x.copy(), w.copy()

    return fresh


@_copies
def legendre_gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The n Legendre-Gauss points (roots of P_n) and weights; exact to degree 2n - 1."""
    n = _check_n(n, 1, "legendre_gauss")

    def f(x):
        P, dP, _ = _legendre(n, x)
        return P[n], dP[n]

    x = _newton(_jacobi_roots(n, 0.0, 0.0), f)
    x = 0.5 * (x - x[::-1])  # the rule is symmetric: make it so exactly (middle node is 0)
    _, dP, _ = _legendre(n, x)
    # (1 - x)(1 + x) rather than 1 - x^2: 1 - x is exact near +1, 1 - x*x loses digits there.
    w = 2.0 / ((1.0 - x) * (1.0 + x) * dP[n] ** 2)
    return x, 0.5 * (w + w[::-1])


@_copies
def legendre_gauss_radau(n: int, end: str = "right") -> tuple[np.ndarray, np.ndarray]:
    """n Legendre-Gauss-Radau points and weights; exact to degree 2n - 2.

    ``end="left"`` includes -1 (roots of P_{n-1} + P_n; GPOPS-II); ``end="right"`` is the
    mirror image, which includes +1 (Radau IIA).
    """
    n = _check_n(n, 1, "legendre_gauss_radau")
    if end not in ("left", "right"):
        raise ValueError(f"legendre_gauss_radau: end must be 'left' or 'right', got {end!r}")

    def f(x):
        P, dP, _ = _legendre(n, x)
        return P[n - 1] + P[n], dP[n - 1] + dP[n]

    # The n - 1 free points are the roots of P_{n-1}^(0,1), i.e. (P_{n-1} + P_n) / (1 + x).
    inner = _newton(_jacobi_roots(n - 1, 0.0, 1.0), f)
    x = np.concatenate(([-1.0], inner))
    P, _, _ = _legendre(n, x)
    w = (1.0 - x) / (n * n * P[n - 1] ** 2)
    w[0] = 2.0 / (n * n)  # the general formula gives 2/n^2 at -1 too; set it exactly
    if end == "right":
        return -x[::-1].copy(), w[::-1].copy()
    return x, w


@_copies
def legendre_gauss_lobatto(n: int) -> tuple[np.ndarray, np.ndarray]:
    """n Legendre-Gauss-Lobatto points (+-1 and the roots of P'_{n-1}) and weights.

    Exact to degree 2n - 3; n >= 2 because both ends are nodes.
    """
    n = _check_n(n, 2, "legendre_gauss_lobatto")

    def f(x):
        _, dP, d2P = _legendre(n - 1, x)
        return dP[n - 1], d2P[n - 1]

    # The n - 2 interior points are the roots of P_{n-2}^(1,1), proportional to P'_{n-1}.
    inner = _newton(_jacobi_roots(n - 2, 1.0, 1.0), f)
    x = np.concatenate(([-1.0], inner, [1.0]))
    x = 0.5 * (x - x[::-1])
    P, _, _ = _legendre(n - 1, x)
    w = 2.0 / (n * (n - 1) * P[n - 1] ** 2)
    return x, 0.5 * (w + w[::-1])


# ----------------------------------------------------------------------------------------
# Barycentric interpolation and differentiation
# ----------------------------------------------------------------------------------------

def _as_nodes(nodes) -> np.ndarray:
    x = np.asarray(nodes, dtype=float)
    if x.ndim != 1 or x.size == 0:
        raise ValueError(f"nodes must be a non-empty 1-D array, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("nodes must be finite")
    if np.unique(x).size != x.size:
        raise ValueError("nodes must be distinct")
    return x


def barycentric_weights(x: np.ndarray) -> np.ndarray:
    """w_j = 1 / prod_{k != j} (x_j - x_k), up to a common factor (which cancels)."""
    # Scaling the differences by 4 / (interval length) keeps the products near 1, so they
    # neither overflow nor underflow for many nodes; the common factor cancels in every use.
    scale = 4.0 / (np.ptp(x) or 1.0)
    diff = (x[:, None] - x[None, :]) * scale
    np.fill_diagonal(diff, 1.0)
    w = 1.0 / np.prod(diff, axis=1)
    return w / np.max(np.abs(w))


def lagrange_matrix(nodes, points) -> np.ndarray:
    """(len(points), len(nodes)) matrix L with L @ f(nodes) = interpolant of f at points.

    Second (true) barycentric formula; a point equal to a node gets the unit row exactly.
    """
    x = _as_nodes(nodes)
    p = np.atleast_1d(np.asarray(points, dtype=float))
    if p.ndim != 1:
        raise ValueError(f"points must be a 1-D array, got shape {p.shape}")
    return barycentric_rows(x, barycentric_weights(x), p)


def barycentric_rows(x: np.ndarray, w: np.ndarray, p: np.ndarray) -> np.ndarray:
    """:func:`lagrange_matrix` with the weights ``w`` of the nodes ``x`` given (a caller that
    evaluates one interpolant many times computes them once)."""
    diff = p[:, None] - x[None, :]
    hit = diff == 0.0
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        terms = w / diff
        L = terms / terms.sum(axis=1, keepdims=True)
    rows = hit.any(axis=1)
    L[rows] = hit[rows].astype(float)
    # a point within ~1e-300 of a node (w / diff overflowed): that node's row
    near = ~np.isfinite(L).all(axis=1) & np.isfinite(p)
    if near.any():
        L[near] = 0.0
        L[near, np.argmin(np.abs(diff[near]), axis=1)] = 1.0
    return L


def differentiation_matrix(nodes) -> np.ndarray:
    """Square D with (D @ f(nodes))_i = derivative of the interpolant at nodes[i].

    Off-diagonal D_ij = (w_j / w_i) / (x_i - x_j); the diagonal is minus the row sum, so
    D annihilates constants to rounding, which is more accurate than the explicit formula.
    """
    x = _as_nodes(nodes)
    w = barycentric_weights(x)
    diff = x[:, None] - x[None, :]
    np.fill_diagonal(diff, 1.0)
    D = (w[None, :] / w[:, None]) / diff
    np.fill_diagonal(D, 0.0)
    np.fill_diagonal(D, -D.sum(axis=1))
    return D


# ----------------------------------------------------------------------------------------
# Schemes
# ----------------------------------------------------------------------------------------

def _frozen(a) -> np.ndarray:
    a = np.array(a)
    a.setflags(write=False)
    return a


# typed=True so that scheme("LG", 3.0) is not answered from the cache entry of ("LG", 3)
# without being validated.
@functools.lru_cache(maxsize=None, typed=True)
def scheme(name: str, degree: int) -> Scheme:
    """The collocation scheme ``name`` with ``degree`` collocation points per segment (cached)."""
    if name not in SCHEME_NAMES:
        raise ValueError(
            f"unknown collocation scheme {name!r}; choose one of {', '.join(SCHEME_NAMES)} "
            "(LGR is the Radau IIA convention that includes the segment end; LGR-start "
            "includes the start, as GPOPS-II does, and is not A-stable)")
    least = 2 if name == "LGL" else 1
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)):
        raise ValueError(f"scheme {name}: degree must be an integer, got {degree!r}")
    if degree < least:
        raise ValueError(
            f"scheme {name}: degree (collocation points per segment) must be >= {least}, "
            f"got {degree}" + (" (LGL needs both segment ends)" if name == "LGL" else ""))
    n = int(degree)

    if name == "LG":
        colloc, weights = legendre_gauss(n)
        support = np.concatenate(([-1.0], colloc))
    elif name == "LGR":
        colloc, weights = legendre_gauss_radau(n, "right")
        support = np.concatenate(([-1.0], colloc))
    elif name == "LGR-start":
        colloc, weights = legendre_gauss_radau(n, "left")
        support = np.concatenate((colloc, [1.0]))
    else:  # LGL
        colloc, weights = legendre_gauss_lobatto(n)
        support = colloc.copy()

    # Every built-in scheme collocates at support points, but the mapping is computed, not
    # assumed, so that D below stays right if a scheme ever collocates elsewhere.
    idx = np.full(n, -1, dtype=int)
    for i, c in enumerate(colloc):
        hit = np.flatnonzero(support == c)
        if hit.size:
            idx[i] = hit[0]
    Ds = differentiation_matrix(support)
    if np.all(idx >= 0):
        D = Ds[idx]
    else:
        # The derivative of the interpolant has degree m - 2, so interpolating the support
        # derivatives to the collocation points is exact.
        D = lagrange_matrix(support, colloc) @ Ds

    return Scheme(
        name=name,
        degree=n,
        support=_frozen(support),
        colloc=_frozen(colloc),
        D=_frozen(D),
        weights=_frozen(weights),
        end_from_support=bool(support[-1] == 1.0),
        colloc_in_support=_frozen(idx),
    )


@functools.lru_cache(maxsize=None)
def lobatto_integration_matrix(n: int) -> np.ndarray:
    """A[i, j] = integral from -1 to tau_i of the j-th Lagrange basis on the n LGL points.

    Used for LGL collocation in integral form (Lobatto IIIA): X_i = X_0 + (h/2) sum_j A_ij F_j.
    Each integral is computed exactly by an n-point Gauss rule mapped onto [-1, tau_i].
    """
    tau, _ = legendre_gauss_lobatto(n)
    g, gw = legendre_gauss(n)
    A = np.zeros((n, n))
    for i in range(1, n):
        half = (tau[i] + 1.0) / 2.0
        pts = -1.0 + (g + 1.0) * half
        A[i] = half * (gw @ lagrange_matrix(tau, pts))
    return _frozen(A)
