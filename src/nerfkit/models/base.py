"""The seams between a method and everything that trains, renders and exports it.

Two families share one `Model` interface (init, per-step aux updates, a declaration of what the
method supports):

    RayModel      renders batches of rays: render_rays(params, aux, o [R,3], d [R,3], key, train)
                  -> {"rgb" [R,3], "depth" [R], "opacity" [R], ...}, and losses(out, target). The
                  trainer's ray step, the one-pass image renderer and per-ray evaluation use it.
    MarchingModel a RayModel that marches an occupancy grid: it exposes its field, grid and sampler
                  (candidates, sample_scale, MIN_TRANSMITTANCE), which the wavefront image renderer,
                  baking and mesh export read.
    ImageModel    renders whole images itself (rasterising primitives: Gaussian splats): its own
                  optimiser and train step, and an image renderer (render_camera(params, aux, c2w,
                  camera) -> {"rgb" [H,W,3], "depth" [H,W], "opacity" [H,W]}, and render_cameras(params,
                  aux, poses, cameras) -> a list of those, as the ray models' renderers have).

Fields (F(x, d) -> rgb, sigma) share one call signature, `Field`, whose `footprint` argument is each kind's
size of a sample (see Field).

What a method supports is declared once, in `supports` (a `Supports`); the trainer, the renderers
and the CLI read it instead of probing for attributes. The settings it reads are declared in `reads`
(training/flags.py refuses the others when given). A new method is one module defining a class
with these members, plus one line in models/registry.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

Params = dict[str, Any]  # a pytree of arrays
Aux = dict[str, Any]  # non-trained state (occupancy grid, density-control statistics)


@dataclass(frozen=True)
class Supports:
    """What a method can do; callers outside models/ read these instead of asking which method it is.

    family:     "rays" (RayModel), "marching" (MarchingModel) or "image" (ImageModel)
    parallel:   what data-parallel training splits over devices: "rays" (each device a slice of the
                batch), "samples" (the packed samples of one batch) or "views" (one view per step)
    step_metrics: the ray step reports extra per-step metrics (model.step_metrics(out) -> dict)
    bake:       `nerfkit bake` can turn a bounded run into a WebGL page of a baked density grid
                (model.field, model.occ: a MarchingModel's field and occupancy grid)
    mesh:       a density field that `export mesh|pointcloud` and grids sample (model.surface_field); its colour
                colours an exported mesh, and `export mesh --method levelset` marches it
    depth:      its renderer gives a view's median depth with its opacity (render_cameras(..., median=True)):
                `export mesh` (TSDF) fuses them; without a density field the mesh's colour comes from the views
    lens:       renders through any COLMAP lens model (rays/cameras.py); without, photos of distorted
                cameras are undistorted for it (data/undistort.py, DataConfig.undistort)
    unbounded:  renders unbounded scenes (--scene-type unbounded, contracted space): the scene type and
                its bound are resolved from the data for it (training/resolve.py)
    sampling:   its samples along a ray are placed by --sampling occupancy|proposal (resolved from the scene)
    appearance: per-image appearance embeddings (--appearance-dim)
    pose_refine: learns a pose correction per training photo (--pose-refine; rays/correction.py)
    fit_poses:  its renderer fits a view's pose to its photo against the frozen scene (renderer.fit_pose(params, aux,
                c2w, camera, image, iterations, fit_colour=False) -> (c2w, {"degrees", "shift"}); `nerfkit eval
                --fit-poses`; fit_colour: the photo's colour fitted alongside, `--fit-colour`)
    gaussians:  its parameters are 3D Gaussians (splat/gaussians.py's layout): export splat, the splat web page and
                the viewer's splat layer read them; its point cloud is their centres
    points:     it starts from the capture's SfM points (Capture.points); model.wants_points(capture) says when a
                capture without them gets points triangulated at its poses first (process/triangulate.py)
    """

    family: str = "rays"
    parallel: str = "rays"
    step_metrics: bool = False
    bake: bool = False
    mesh: bool = True
    depth: bool = True
    lens: bool = True
    unbounded: bool = False
    sampling: bool = False
    appearance: bool = True
    pose_refine: bool = False
    fit_poses: bool = False
    gaussians: bool = False
    points: bool = False

    @property
    def marching(self) -> bool:
        return self.family == "marching"

    @property
    def renders_images(self) -> bool:
        return self.family == "image"


@runtime_checkable
class Field(Protocol):
    """F(x, d) -> (rgb, sigma), one call signature for every kind of field (fields/, models/baked/):

        field(params, x [..., 3], d [..., 3] or broadcastable, emb [..., A] | None, footprint=None)
            -> rgb [..., 3], sigma [...]
        field.density(params, x, footprint=None) -> sigma [...]
        field.embedding(params, image_idx) -> appearance embeddings [R, A] (None: the field has none)

    `footprint` is the size of the region each sample stands for (its pixel's cone at that depth), in the
    form the kind's encoding integrates over; None: a point, encoded as such.

        mlp / mip (fields/mlp.py)  the diagonal covariance var [..., 3] of the Gaussian x ~ N(mean, diag(var))
                                   of a conical frustum: the integrated positional encoding (mip-NeRF)
        ngp (fields/ngp.py)        the std s [...] of the pixel footprint in world units: hash-grid levels
                                   finer than s are faded out (--antialias; MarchingModel.sample_scale)
        baked (models/baked/)      ignored (one grid resolution)
    """

    def __call__(self, params: Params, x, d, emb=None, footprint=None) -> tuple:
        """(rgb [..., 3], sigma [...]) at x seen along unit directions d."""

    def density(self, params: Params, x, footprint=None):
        """sigma [...] at x [..., 3]."""

    def embedding(self, params: Params, image_idx):
        """Appearance embeddings of training images image_idx [R] (None: their mean), or None."""


@runtime_checkable
class Model(Protocol):
    """What every method has."""

    supports: ClassVar[Supports]
    title: ClassVar[str]  # its name in messages: "hash-grid (ngp)"
    reads: ClassVar[frozenset[str]]  # the settings ("section.field") it reads beyond those every method reads
    loss_name: str  # its training loss in words ("MSE"), the label of the loss curve

    @staticmethod
    def describe(cfg) -> str:
        """One line naming the model that `cfg` makes, with the settings it reads (and only those)."""

    # Optional (models/registry.py supplies "no rule" where a method has none):
    #   check(cfg) -> None: ConfigError for a combination of its settings it cannot run with
    #   unused(cfg, capture) -> {setting: why}: settings it leaves unread at these values (e.g. --l-dir
    #       without view directions); training/flags.py refuses them when given

    def init(self, key) -> tuple[Params, Aux]:
        """Initial (params, aux)."""


@runtime_checkable
class RayModel(Model, Protocol):
    """A method that renders rays (the NeRF family)."""

    rays_per_step: int  # rays drawn per training step (--batch-rays, or what the model's sample budget holds)

    def update_aux(self, params: Params, aux: Aux, step, key) -> Aux:
        """aux after a training step (e.g. an occupancy-grid refresh); identity where nothing changes."""

    def render_rays(self, params: Params, aux: Aux, o, d, key, train: bool, image_idx=None, radii=None) -> dict:
        """{"rgb" [R, 3], "depth" [R], "opacity" [R], ...} for rays o + t d."""

    def losses(self, out: dict, target, weights=None) -> tuple:
        """(total loss, fine-image mse) of a batch against target [R, 3]."""


@runtime_checkable
class MarchingModel(RayModel, Protocol):
    """A RayModel that marches an occupancy grid (the wavefront renderer, bake and export read these)."""

    MIN_TRANSMITTANCE: ClassVar[float]
    field: Field  # and to_grid(x), radius, unbounded (the marcher's grid coordinates)
    occ: Any  # sampling.occupancy.OccupancyConfig

    def candidates(self, o, d, key=None, index=None) -> tuple:
        """Candidate sample positions t [R, K] along the rays (and their intervals)."""

    def sample_scale(self, t, dir_norm, radii):
        """The field's footprint of each sample at t on rays of |d| dir_norm and cone radii (None without
        cones, or where the field does not use it)."""


@runtime_checkable
class ImageRenderer(Protocol):
    def render_camera(self, params: Params, aux: Aux, c2w, camera) -> dict:
        """{"rgb" [H, W, 3], "depth" [H, W], "opacity" [H, W]} of one camera."""


@runtime_checkable
class ImageModel(Model, Protocol):
    """A method that renders whole images by rasterising primitives (Gaussian splats)."""

    def bind_data(self, capture, data, log=print) -> None:
        """Take what initialisation needs from the training data (extent, SfM points)."""

    def make_optimizer(self, cfg) -> tuple:
        """(optimiser with .init(params), schedule(step) for the log)."""

    def make_train_step(self, optimizer, data, cfg, mesh=None):
        """step(state, step, images, poses) -> (state, metrics)."""

    def renderer(self, chunk: int = 0) -> ImageRenderer:
        """The image renderer."""
