"""Pose solves during training (--pose-solves N, with --pose-refine on): N times over the budget, every training
photo's pose correction xi_k (rays/correction.py: c2w_k T(xi_k), translations in units of the scene extent) takes
one Levenberg-Marquardt iteration (pose_fit.py) against the Gaussians as they stand, with its colour transform
applied where the run learns one:

    xi_k <- xi_k + a (x_k - xi_k),   x_k = one LM iteration from xi_k on  |R(c2w_k T(x)) - I_k|^2

with a the share of the step taken (--pose-solve-share, 1: all of it).

Adam alone crawls along each pose's orbit about the scene's centre (a turn and the shift that keeps the centre in
view change a photo little, so the two are nearly one direction of its 6 parameters, which a per-parameter step
cannot follow; pose_fit.py), and the Gaussians bend to hold what is left. A Gauss-Newton step solves that 6 x 6
system whole. Between solves Adam goes on moving the corrections with the Gaussians.

The solves fall where the progress within the run (within the round, --pose-rounds) crosses

    t_j = s + (1 - s) j / N,   j = 1 .. N,   s = the end of the pose warm-up (optim.pose_lr: 2 pose_warmup)

so the last comes after the last step. Each costs 13 or more renders per training photo (docs: Splats).

A scene that is still forming draws the cameras' orbit positions off a little, all one way (docs: Corrections),
and grows around where the solve put them, so the next solve starts from there: the pull adds up over a run's
solves. A share a < 1 takes that much of each pull (and of each correction), so that the photos, which hold the
orbit weakly, keep more of their say between solves.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from nerfkit.core.errors import ConfigError
from nerfkit.models.splat.gaussians import PARAM_NAMES
from nerfkit.models.splat.optim import LearningRates
from nerfkit.models.splat.pose_fit import fit_correction

# per solve (probes on the ring capture at 64 px: 13 solves of one iteration left 0.21 degrees, 4 of three 0.24)
ITERATIONS = 1
HIDDEN_OPACITY = -30.0  # the logit an inactive slot is drawn with (sigmoid: 1e-13, under the rasteriser's cut)


def check_settings(g) -> None:
    """ConfigError for the splat settings g (config.SplatSettings) where --pose-rounds is under 1 (under 2 with
    --pose-hold-last on), --pose-solves under 0, --pose-solve-share outside (0, 1], --pose-warmup outside [0, 0.5)
    (the solves start at twice it), or --pose-lr under 0, or 0 without solves (nothing would move the poses)."""
    if g.pose_rounds < 1:
        raise ConfigError(f"--pose-rounds must be at least 1 (got {g.pose_rounds}); 1: one round")
    if g.pose_hold_last == "on" and g.pose_rounds < 2:
        raise ConfigError(f"--pose-hold-last on needs --pose-rounds 2 or more (got {g.pose_rounds}): the rounds before "
                          f"the last refine the poses it holds")
    if g.pose_solves < 0:
        raise ConfigError(f"--pose-solves must be at least 0 (got {g.pose_solves}); 0: Adam alone")
    if not 0.0 < g.pose_solve_share <= 1.0:
        raise ConfigError(f"--pose-solve-share must be in (0, 1] (got {g.pose_solve_share:g}); 1: each solve's "
                          f"whole step")
    if not 0.0 <= g.pose_warmup < 0.5:
        raise ConfigError(f"--pose-warmup must be in [0, 0.5) (got {g.pose_warmup:g}): the poses' rate ramps up "
                          f"until twice it and the solves come after; {LearningRates.pose_warmup:g}: the default")
    if not (g.pose_lr >= 0.0 and np.isfinite(g.pose_lr)):
        raise ConfigError(f"--pose-lr must be at least 0 (got {g.pose_lr:g}); {LearningRates.cam_pose:g}: the default")
    if g.pose_lr == 0.0 and g.pose_solves == 0:
        raise ConfigError("--pose-lr 0 leaves only the solves to move the poses, and there are none; add "
                          "--pose-solves N (16: docs: Corrections) or give --pose-lr a rate")


def unused_settings(refine: bool, solves: int) -> dict[str, str]:
    """{setting: why} of the pose settings a run leaves unread: all of them without pose refinement (refine False),
    --pose-solve-share without solves."""
    off = "pose refinement is off (--pose-refine on)"
    out = dict.fromkeys(("splat.pose_rounds", "splat.pose_hold_last", "splat.pose_solves", "splat.pose_warmup",
                         "splat.pose_lr"),
                        off) if not refine else {}
    if not refine or solves == 0:
        out["splat.pose_solve_share"] = "the run makes no pose solves (--pose-refine on --pose-solves N)"
    return out


def describe_pose(cfg) -> str:
    """The pose settings' part of the run's one-line description (SplatModel.describe): empty without pose refinement,
    else the rounds, the solves, and the warm-up and rate where they are not the defaults."""
    n, k, w = cfg.splat.pose_rounds, cfg.splat.pose_solves, cfg.splat.pose_warmup
    solves = f" ({k} pose solve{'s' * (k > 1)}{' a round' * (n > 1)})" if k else ""
    held = f", poses held for the first {100 * w:g}%{' of each round' * (n > 1)}" if w else ", poses free from the start"
    warm = held if w != LearningRates.pose_warmup else ""
    rounds = f" in {n} rounds{', the last holding the poses' * (cfg.splat.pose_hold_last == 'on')}" if n > 1 else ""
    lr = cfg.splat.pose_lr
    rate = "" if lr == LearningRates.cam_pose else f", pose rate {lr:g}" if lr else ", poses moved by the solves alone"
    return "" if cfg.train.pose_refine != "on" else f"; pose refinement{rounds}{solves}{warm}{rate}"


def solves_done(progress: float, n: int, start: float) -> int:
    """How many of the n solves t_j (module docstring) progress t has reached: floor(n clip((t - s) / (1 - s)))."""
    if n <= 0:
        return 0
    return int(np.floor(n * np.clip((progress - start) / max(1.0 - start, 1e-9), 0.0, 1.0) + 1e-9))


def solve_due(before: float, after: float, n: int, start: float) -> bool:
    """Whether a step that took the progress from before to after crossed a solve t_j."""
    return solves_done(after, n, start) > solves_done(before, n, start)


def solve_corrections(params: dict, active, poses, images, intrinsics, extent: float, width: int, height: int,
                      background, sh_degree: int, backend: str, dilation: float,
                      iterations: int = ITERATIONS, share: float = 1.0) -> np.ndarray:
    """cam_pose [V, 6] after one solve (module docstring; `iterations` LM iterations, a = share) of every training
    photo: poses [V, 4, 4] the photos' given poses, images [V, H, W, 3 or 4] (RGBA views: their colour is already on
    the background), intrinsics [V, 4]; params the run's (with "cam_pose" [V, 6] and, where learned, "cam_color"
    [V, 3, 4]); active [capacity] the slots in use."""
    scene = {k: jnp.asarray(params[k]) for k in PARAM_NAMES}
    scene["opacity"] = jnp.where(jnp.asarray(active), scene["opacity"], HIDDEN_OPACITY)
    start = np.asarray(params["cam_pose"], np.float64)
    color = np.asarray(params["cam_color"]) if "cam_color" in params else None
    xi = np.stack([fit_correction(scene, poses[k], start[k], extent, intrinsics[k], width, height, images[k],
                                  background, sh_degree, iterations, backend, dilation,
                                  None if color is None else color[k]) for k in range(len(start))])
    if share != 1.0:
        xi = start + share * (xi - start)
    return xi.astype(np.float32)
