"""Meshes: segment breakpoints in normalised time s in [0, 1] and a degree per segment."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .nodes import Scheme, scheme


@dataclass(frozen=True, eq=False)
class Mesh:
    scheme_name: str
    breakpoints: np.ndarray        # (K+1,), 0 ... 1
    degrees: tuple[int, ...]       # (K,)

    @classmethod
    def uniform(cls, scheme_name: str, segments: int | list[float], degree: int | list[int]) -> "Mesh":
        bp = np.linspace(0.0, 1.0, segments + 1) if isinstance(segments, int) else np.asarray(segments, float)
        k = len(bp) - 1
        degrees = (degree,) * k if isinstance(degree, int) else tuple(degree)
        if len(degrees) != k:
            raise ValueError(f"{len(degrees)} degrees given for {k} segments")
        return cls(scheme_name, bp, degrees)

    @property
    def segments(self) -> int:
        return len(self.degrees)

    def bisected(self) -> "Mesh":
        """Every segment split at its middle, each half of the segment's degree (its
        polynomials are the restrictions of this mesh's: a finer space, not another one)."""
        bp = self.breakpoints
        halves = np.empty(2 * len(bp) - 1)
        halves[0::2], halves[1::2] = bp, 0.5 * (bp[:-1] + bp[1:])
        return Mesh(self.scheme_name, halves, tuple(d for d in self.degrees for _ in range(2)))

    def scheme(self, k: int) -> Scheme:
        return scheme(self.scheme_name, self.degrees[k])

    def describe(self) -> dict:
        return {"transcription": self.scheme_name, "segments": self.segments,
                "degrees": list(self.degrees), "breakpoints": self.breakpoints.tolist()}


@dataclass(frozen=True, eq=False)
class Layout:
    """Where every unknown of one phase lives on a mesh.

    State nodes are numbered 0..n_state_nodes-1 along time (segment ends are shared with the
    next segment's start); control nodes are the collocation points, numbered along time.
    For each segment: ``support`` (global state-node index of each support point),
    ``colloc_state`` (state node of each collocation point), ``colloc`` (control node of each
    collocation point) and ``end`` (state node of the segment's end).
    """

    mesh: Mesh
    s_state: np.ndarray            # normalised time of each state node
    s_colloc: np.ndarray           # normalised time of each collocation node
    support: list[np.ndarray]
    colloc_state: list[np.ndarray]
    colloc: list[np.ndarray]
    end: list[int]
    colloc_segment: np.ndarray     # segment of each collocation node

    @classmethod
    def of(cls, mesh: Mesh) -> "Layout":
        s_state, s_colloc = [0.0], []
        support, colloc_state, colloc, ends, seg_of = [], [], [], [], []
        for k in range(mesh.segments):
            sc = mesh.scheme(k)
            a, b = mesh.breakpoints[k], mesh.breakpoints[k + 1]
            to_s = lambda tau: a + (np.asarray(tau) + 1.0) * (b - a) / 2.0  # noqa: E731
            start = len(s_state) - 1
            idx = [start]
            inner = sc.support[1:] if sc.end_from_support else sc.support[1:]
            for tau in inner:
                s_state.append(float(to_s(tau)))
                idx.append(len(s_state) - 1)
            if not sc.end_from_support:
                s_state.append(float(b))       # LG: the end is a state node but not a support point
                ends.append(len(s_state) - 1)
            else:
                ends.append(idx[-1])
            idx = np.array(idx)
            support.append(idx)
            colloc_state.append(idx[np.asarray(sc.colloc_in_support)])
            first = len(s_colloc)
            s_colloc.extend(float(x) for x in to_s(sc.colloc))
            colloc.append(np.arange(first, len(s_colloc)))
            seg_of.extend([k] * len(sc.colloc))
        return cls(mesh, np.array(s_state), np.array(s_colloc), support, colloc_state, colloc, ends,
                   np.array(seg_of))

    @property
    def n_state_nodes(self) -> int:
        return len(self.s_state)

    @property
    def n_colloc(self) -> int:
        return len(self.s_colloc)
