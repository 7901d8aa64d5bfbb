"""The secant memory of ``switches.move_switches`` pairs a switch with its own previous record,
not with the record of the switch that had the same order among those located last time."""
from types import SimpleNamespace

import numpy as np
import pyomo.environ as pyo
import pytest

from ocdsl.solve.mesh import switches
from ocdsl.transcribe.mesh import Mesh

# dJ*/ds of each (stand-in) switch: linear, stationary at S_A and S_B
S_A, S_B, K = 0.31, 0.52, 100.0


def _tr(bps):
    m = pyo.ConcreteModel()
    m.x = pyo.Var(initialize=0.0)
    m.obj = pyo.Objective(expr=m.x, sense=pyo.minimize)
    phase = SimpleNamespace(name="main", t0=0.0, tf=None)          # free final time
    layout = SimpleNamespace(mesh=Mesh("LGR", np.asarray(bps, float), (4,) * (len(bps) - 1)))
    return SimpleNamespace(model=m, phases=[SimpleNamespace(phase=phase, layout=layout)])


def _gradient(tr, rebuild, name, q):
    s = float(tr.phases[0].layout.mesh.breakpoints[q])
    if abs(s - 0.2) < 1e-12:          # a spurious switch on breakpoint 0.2
        return 1.0
    return K * (s - (S_A if s < 0.4 else S_B))


SPEC = SimpleNamespace(corner_tolerance=1e-6, snap=0.1, tolerance=1e-6)


def _move(bps, located, memory):
    def resolve(meshes):
        return -1.0           # every trial move lowers J (J = 0 as solved)
    return switches.move_switches(_tr(bps), None, resolve, {"main": list(located)}, {"main": list(located)},
                                  SPEC, memory, 0.0)["main"]


@pytest.fixture
def first(monkeypatch):
    """Both switches pinned on breakpoints 0.3 and 0.5: first steps of 0.05 of a segment."""
    monkeypatch.setattr(switches, "breakpoint_gradient", _gradient)
    memory: dict = {}
    out = _move([0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1], [0.3, 0.5], memory)
    assert out == pytest.approx([0.305, 0.505])
    return memory


# the next mesh: the breakpoints on the first targets
NEXT = [0, 0.1, 0.2, 0.305, 0.4, 0.505, 0.6, 0.8, 1]


def test_missed_switch_does_not_lend_its_record(first):
    """Only the second switch is located: its secant uses its own record (0.5, -2), and lands on
    its stationary point 0.52; paired with the first switch's record (order 0 before the fix)
    the slope came out negative and the breakpoint took another first step, to 0.50975."""
    out = _move(NEXT, [0.505], first)
    assert out == pytest.approx([S_B], abs=1e-9)
    # the missed switch's record is not kept as if current
    assert [r[0] for r in first["main"]] == pytest.approx([0.505])


def test_spurious_switch_gets_no_record(first):
    """A spurious extra switch on breakpoint 0.2 before both: the real ones still pair with their
    own records (secant targets 0.31 and 0.52), the spurious one with none."""
    out = _move(NEXT, [0.2, 0.305, 0.505], first)
    assert out[1:] == pytest.approx([S_A, S_B], abs=1e-9)
    assert out[0] == pytest.approx(0.2 - 0.05 * 0.1)     # a first step, no secant


def test_pair_records():
    records = [(0.3, -1.0, 0.2, 0.4), (0.5, -2.0, 0.4, 0.6)]
    assert switches._pair_records(records, [0.505]) == [1]
    assert switches._pair_records(records, [0.305, 0.505]) == [0, 1]
    # a breakpoint outside every record's neighbouring segments: none
    assert switches._pair_records(records, [0.7]) == [None]
    # one record serves one switch: the nearer of two in its segments takes it
    assert switches._pair_records(records[:1], [0.25, 0.31]) == [None, 0]


def test_a_secant_across_the_kink_moves_nothing_untried(monkeypatch):
    """A pinned switch whose record lies on the other side of J*'s kink (dJ*/ds negative there
    and less negative here: a negative secant slope) is no minimum to aim for: the move is
    tried first and, where the trial does not lower J, not made (it was made untried)."""
    monkeypatch.setattr(switches, "breakpoint_gradient", lambda tr, rb, n, q: -1.0 if
                        abs(float(tr.phases[0].layout.mesh.breakpoints[q]) - 0.3) < 1e-12 else -0.5)
    memory = {"main": [(0.29, -0.5, 0.2, 0.4)]}           # slope (-1 - -0.5) / 0.01 = -50
    tried = []

    def resolve_higher(meshes):
        tried.append(1)
        return 1.0            # the trial raises J (J = 0 as solved)

    out = switches.move_switches(_tr([0, 0.1, 0.2, 0.3, 0.4, 0.5, 1]), None, resolve_higher, {"main": [0.3]},
                                 {"main": [0.3]}, SPEC, memory, 0.0)["main"]
    assert tried and out == [0.3]
    out = _move([0, 0.1, 0.2, 0.3, 0.4, 0.5, 1], [0.3], {"main": [(0.29, -0.5, 0.2, 0.4)]})
    assert out == pytest.approx([0.3 + 0.05 * 0.1])     # tried, lower: the first step
