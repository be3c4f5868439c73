"""Pose refinement in rounds (--pose-rounds N, with --pose-refine on): the budget split into N equal rounds, each
running the whole schedule; at each round's first step but the first's, the Gaussians start over from the run's
initial points (their optimiser state, density-control statistics and SH degree too) while each training photo's
corrections (cam_pose, cam_color) are kept. A scene fitted with wrong poses bends to hold them, and more steps fit
the bent scene more closely; a scene formed afresh at the poses the round before mended has no such bend to keep
(docs: Splats, pose refinement).

With progress t in [0, 1] (the budget used) the round is r = min(floor(N t), N - 1) and the progress within it
u = N t - r; the step within it counts from the step at which it began (aux "round_start", kept in checkpoints,
so that a resumed run goes on in the same round).
"""

from __future__ import annotations

import numpy as np


def round_of(progress: float, rounds: int) -> tuple[int, float]:
    """(r, u): the round r = min(floor(N t), N - 1) of progress t in [0, 1] with N = rounds, and the progress
    u = N t - r in [0, 1] within it."""
    r = min(int(progress * rounds), rounds - 1)
    return r, float(min(1.0, progress * rounds - r))


def within_round(progress: float, rounds: int, aux: dict) -> float:
    """The progress within the round aux["round"] (0 without rounds) at run progress t: u of round_of(t), or 1
    where t is already in a later round (the step that ended the round)."""
    r, u = round_of(progress, rounds)
    return 1.0 if r > int(aux.get("round", 0)) else u


def round_aux(rounds: int) -> dict:
    """The state's extra aux entries for rounds > 1: {"round", "round_start"} int32 scalars at 0; none for 1."""
    return {"round": np.zeros((), np.int32), "round_start": np.zeros((), np.int32)} if rounds > 1 else {}


def in_round(state: dict, step: int, progress: float, rounds: int, init, corrections,
             optimizer) -> tuple[dict, int, float]:
    """(state, step, progress) as round r = round_of(progress, rounds)[0] sees them. At the first step of a round
    later than the state's, the state starts over: (params, aux) = init() with the groups named in `corrections`
    taken from the state's params, the optimiser state optimizer.init(params) and aux's clock kept. The step
    returned counts from the round's first step; the progress is u within the round."""
    r, within = round_of(progress, rounds)
    if r > int(state["aux"]["round"]):
        params, aux = init()
        params.update({k: state["params"][k] for k in corrections})
        aux.update(clock=state["aux"]["clock"], round=np.int32(r), round_start=np.int32(step))
        state = {"params": params, "opt_state": optimizer.init(params), "aux": aux}
    return state, step - int(state["aux"]["round_start"]), within
