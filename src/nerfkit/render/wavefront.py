"""The wavefront renderer of occupancy-marched fields (WavefrontRenderer: each ray stops where it is spent,
empty space skipped by empty_space.py), and the coarser march the viewer's moving previews use."""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.render.chunked import Renderer
from nerfkit.render.empty_space import empty_distance, first_set_bits, pack_bits, skip_empty
from nerfkit.sampling import occupancy


class WavefrontRenderer(Renderer):
    """Full-image rendering for occupancy-marched fields that stops each ray where it is spent.

    `chunk` slots each hold one ray. Every round, each live ray first skips the candidates
    that the occupancy grid's distance field proves empty (skip_empty: sphere tracing over
    empty_distance, on the march's own t grid), then looks at its next WINDOW candidate
    intervals (model.candidates; the same t grid as training's march, without jitter) and
    marks those in occupied cells in a bit mask; up to CAP marked ones are shaded: density
    and colour, weights w_i = T_i (1 - exp(-sigma_i delta_i)) with T carried over from
    earlier rounds, accumulated into the ray's colour, depth and opacity. A ray retires when
    T < MIN_TRANSMITTANCE or its candidates run out, and the next pending ray takes its
    slot. So empty space costs a few distance look-ups, and nothing behind a surface is
    shaded (beyond the last window). The shaded samples of all slots are packed (ray-major,
    offsets from a prefix sum of per-ray counts, starting at a round-robin slot) into the
    smallest of a few fixed budgets that holds them, or the largest: rays past it shade
    fewer samples this round and go on from their first unshaded one next round, so the
    budget is full and padding small. Compositing runs on a dense [chunk, CAP] layout.
    Pixels equal the one-pass renderer's (same samples, same weights) up to float
    summation order.
    """

    # Measured on a 10-minute lego ngp run, 2 CPU cores, compiled (benchmarks/render_speed.py): one
    # 800x800 frame 3.75 s / 256x256 0.40 s with chunk 4096, budgets (1, 2, 4), WINDOW 64, CAP 8; budgets
    # (1, 4, 8) 4.22 s (more padding); WINDOW 32 3.79 s; chunk 8192 3.26-3.45 s (make_renderer's choice);
    # chunk 2048 4.90 s. Budgets of 65536 samples run slower per sample than 32768 (cache).
    WINDOW = 64  # a multiple of 32 (bit-mask words)
    CAP = 8
    BUDGETS = (1, 2, 4)  # samples per slot: a round's budget is chunk * m for the smallest m that holds it
    # On a GPU a round is a few device calls whatever its size, so every ray of an image is put in flight at
    # once (slots: the rays rounded up to a power of two, at most GPU_MAX_SLOTS): a frame then takes about as
    # many rounds as its longest ray needs, not that times the image's rays / chunk (tests/models/test_ngp.py
    # holds it to the same pixels in fewer rounds). On a CPU rounds that large run slower (caches), so there
    # the slots stay `chunk`.
    GPU_MAX_SLOTS = 1 << 19

    def __post_init__(self):
        self._by_slots: dict[int, tuple] = {}
        self._window, self._shade = self._rounds(self.chunk)
        self._dist = None
        self.last_rounds = self.last_shaded = 0  # of the last march: rounds that shaded, samples shaded

    def slots_for(self, n: int) -> int:
        """Ray slots for a march of n rays: `chunk`, or on a GPU n rounded up to a power of two (at least
        chunk, at most GPU_MAX_SLOTS)."""
        if jax.default_backend() != "gpu":
            return self.chunk
        return int(min(self.GPU_MAX_SLOTS, max(self.chunk, 1 << max(0, int(n) - 1).bit_length())))

    def _rounds(self, r: int) -> tuple:
        """(window, {m: shade}): the round functions, jitted for r slots (built once per r)."""
        if r not in self._by_slots:
            self._by_slots[r] = self._make_rounds(r)
        return self._by_slots[r]

    def _make_rounds(self, r: int) -> tuple:
        model = self.model
        w, cap = self.WINDOW, self.CAP
        steps = jnp.arange(w, dtype=jnp.int32)

        field = model.field
        lipschitz = field.lipschitz

        def window(aux, dist, o, d, k0):
            k0 = skip_empty(model.candidates, field.to_grid, model.occ, dist, lipschitz, o, d, k0)
            t0, t1, cand = model.candidates(o, d, None, k0[:, None] + steps[None, :])
            x = o[:, None, :] + (0.5 * (t0 + t1))[..., None] * d[:, None, :]
            occ = occupancy.query_occupancy(aux, field.to_grid(x.reshape(-1, 3)), model.occ).reshape(r, w)
            keep = cand & occ
            return pack_bits(keep), jnp.sum(jnp.minimum(jnp.sum(keep, axis=1), cap)), ~cand[:, -1], k0

        def shade(params, o, d, rad, k0, bits, trans, half, first, budget):
            pos, ok, rest = first_set_bits(bits, cap)  # [r, cap]
            count = jnp.sum(ok, axis=1)
            # Packing order starts at slot `first` (round robin, so no slot waits for ever); rays past the
            # budget shade fewer samples (or none) this round and go on from their first unshaded one.
            rolled = jnp.roll(count, -first)
            start = jnp.roll(jnp.cumsum(rolled) - rolled, first)  # first packed sample of each ray
            take = jnp.clip(budget - start, 0, count)
            ok = ok & (jnp.arange(cap)[None, :] < take[:, None])
            slot = jnp.where(ok, start[:, None] + jnp.arange(cap)[None, :], budget)
            # Inverse map of the packing: packed sample s -> (ray, j); slots past the total stay ray 0.
            src = jnp.zeros(budget, jnp.int32).at[slot.reshape(-1)].set(jnp.arange(r * cap, dtype=jnp.int32),
                                                                           mode="drop")
            ray = src // cap
            t0, t1, _ = model.candidates(o, d, None, k0[:, None] + pos)  # [r, cap]
            t_mid = 0.5 * (t0 + t1)
            norm = jnp.linalg.norm(d, axis=-1)
            emb = model.field.embedding(params["field"], None)
            t_s = t_mid.reshape(-1)[src]
            rgb, sigma = model.field(params["field"], o[ray] + t_s[:, None] * d[ray], d[ray] / norm[ray][:, None], emb,
                                     footprint=model.sample_scale(t_s, norm[ray], rad[ray]))
            back = jnp.minimum(slot, budget - 1)  # [r, cap]: each sample's packed position
            tau = jnp.where(ok, sigma[back] * (t1 - t0) * norm[:, None], 0.0)
            t_i = trans[:, None] * jnp.exp(-(jnp.cumsum(tau, axis=1) - tau))
            wgt = jnp.where(ok & (t_i >= model.MIN_TRANSMITTANCE), t_i * (1.0 - jnp.exp(-tau)), 0.0)
            # The median depth (volume.py): the sample where T crosses `half` = 1 - A / 2 (A: the ray's
            # opacity, from a first pass), T_i > half >= T_i e^-tau: once per ray over all rounds, so it
            # adds up like the depth. half < 0 never crosses.
            cross = ok & (t_i > half[:, None]) & (t_i * jnp.exp(-tau) <= half[:, None])
            return {"rgb": jnp.sum(wgt[..., None] * rgb[back], axis=1), "depth": jnp.sum(wgt * t_mid, axis=1),
                    "depth_median": jnp.sum(jnp.where(cross, t_mid, 0.0), axis=1),
                    "opacity": jnp.sum(wgt, axis=1), "trans": trans * jnp.exp(-jnp.sum(tau, axis=1)),
                    "k_next": jnp.where(take < count, k0 + jnp.take_along_axis(pos, jnp.minimum(take, cap - 1)[:, None],
                                                                              axis=1)[:, 0],
                                        jnp.where(rest >= 0, k0 + rest, k0 + w)),
                    "next_first": (first + jnp.argmax(jnp.roll(take < count, -first))) % r,
                    "shaded": jnp.sum(take)}

        return jax.jit(window), {m: jax.jit(partial(shade, budget=r * m)) for m in self.BUDGETS}

    def empty_distance(self, aux) -> jnp.ndarray:
        """empty_distance of the occupancy bits in aux, computed once per bits array (the viewer renders
        many frames of one grid)."""
        bits = aux["bits"]
        if self._dist is None or self._dist[0] is not bits:
            self._dist = (bits, jnp.asarray(empty_distance(np.asarray(bits), self.model.occ.resolution)))
        return self._dist[1]

    def _free_slots(self, r: int | None = None) -> tuple[np.ndarray, ...]:
        """The state of r (default `chunk`) free slots: o, d [r, 3], radii, k0 (far past every candidate) and
        transmittance [r], with the shapes and dtypes the round functions are compiled for."""
        r = self.chunk if r is None else r
        return (np.zeros((r, 3), np.float32), np.tile(np.array([[0.0, 0.0, 1.0]], np.float32), (r, 1)),
                np.zeros(r, np.float32), np.full(r, 1 << 30, np.int32), np.ones(r, np.float32))

    def warm_up(self, params, aux) -> None:
        """Compile the round functions (the window and every shading budget) on `chunk` free slots, so that
        no later frame waits for a compile (the viewer calls this in idle time). On a GPU a frame marches
        with slots_for(its rays) and compiles that size on its first use."""
        o, d, rad, k0, trans = self._free_slots()
        bits, _, _, k0 = self._window(aux, self.empty_distance(aux), o, d, k0)
        k0 = np.array(k0)
        for m in self.BUDGETS:
            jax.block_until_ready(self._shade[m](params, o, d, rad, k0, bits, trans, -trans, 0))

    def render_rays(self, params, aux, origins: np.ndarray, directions: np.ndarray,
                    radii: np.ndarray | None = None, median: bool = False) -> dict:
        """Render rays [N, 3] (cones of radii [N], see Renderer.render_rays); returns numpy arrays rgb [N, 3],
        depth, depth_normalized, opacity [N], and with `median` depth_median [N] (volume.py: where the
        running opacity reaches half the ray's opacity; a second march of the rays, since a ray's
        opacity is known only once it is spent)."""
        n = origins.shape[0]
        radii = np.zeros(n, np.float32) if radii is None else np.broadcast_to(np.asarray(radii, np.float32), (n,))
        acc = self._march(params, aux, origins, directions, radii, np.full(n, -1.0, np.float32))
        opacity = acc["opacity"]
        rgb = acc["rgb"] + (1.0 - opacity[:, None]) * np.asarray(self.model.background)
        depth_norm = np.where(opacity > 1e-6, acc["depth"] / np.maximum(opacity, 1e-6), self.model.far)
        out = {"rgb": rgb.astype(np.float32), "depth": acc["depth"], "depth_normalized": depth_norm.astype(np.float32),
               "opacity": opacity}
        if median:
            half = np.where(opacity > 1e-6, 1.0 - 0.5 * opacity, -1.0).astype(np.float32)
            again = self._march(params, aux, origins, directions, radii, half)["depth_median"]
            crossed = (opacity > 1e-6) & (again > 0)  # (float rounding can miss the crossing of a nearly clear ray)
            out["depth_median"] = np.where(crossed, again, self.model.far).astype(np.float32)
        return out

    def _march(self, params, aux, origins, directions, radii, half) -> dict:
        """The rounds of the wavefront (class docstring) over rays [N, 3] with median thresholds half [N]
        (-1: none): the sums rgb [N, 3], depth, depth_median, opacity [N] of the shaded samples."""
        n = origins.shape[0]
        r = self.slots_for(n)
        window, shade = self._rounds(r)
        acc = {"rgb": np.zeros((n, 3), np.float32), "depth": np.zeros(n, np.float32),
               "depth_median": np.zeros(n, np.float32), "opacity": np.zeros(n, np.float32)}
        slot_ray = np.full(r, -1)
        o, d, rad, k0, trans = self._free_slots(r)
        self.last_rounds = self.last_shaded = 0
        slot_half = -np.ones(r, np.float32)
        dist = self.empty_distance(aux)
        nxt = first = 0
        while True:
            free = np.flatnonzero(slot_ray < 0)
            take = free[: n - nxt]
            if take.size:
                ids = np.arange(nxt, nxt + take.size)
                nxt += take.size
                slot_ray[take], o[take], d[take], k0[take], trans[take] = ids, origins[ids], directions[ids], 0, 1.0
                rad[take], slot_half[take] = radii[ids], half[ids]
            live = slot_ray >= 0
            if not live.any():
                break
            bits, shaded, exhausted, k0 = window(aux, dist, o, d, k0)
            shaded, exhausted, k0 = int(shaded), np.asarray(exhausted), np.array(k0)
            if shaded:
                m = min([m for m in self.BUDGETS if r * m >= shaded] or [max(self.BUDGETS)])
                res = shade[m](params, o, d, rad, k0, bits, trans, slot_half, first)
                self.last_rounds += 1
                self.last_shaded += int(res["shaded"])
                first = int(res["next_first"])
                ids = slot_ray[live]
                for key in acc:
                    acc[key][ids] += np.asarray(res[key])[live]
                trans = np.asarray(res["trans"]).copy()
                k_next = np.asarray(res["k_next"]).astype(np.int32)
            else:
                k_next = k0 + self.WINDOW
            # Spent: past the last candidate with nothing left in the window, or opaque.
            done = (exhausted & (k_next - k0 >= self.WINDOW)) | (trans < self.model.MIN_TRANSMITTANCE)
            k0 = k_next
            retire = live & done
            slot_ray[retire] = -1
            k0[retire] = 1 << 30
        return acc


class CoarseMarch:
    """A marching model seen with an s times longer step: its candidate k is the union of the model's
    candidates s k .. s k + s - 1, the interval [t_start(s k), t_end(s k + s - 1)].

    These intervals tile the same t range as the model's own, s times longer: exactly the march of
    the model with march_steps / s (box and contraction alike), on the same occupancy grid and
    field. The viewer's moving previews use it (about s times fewer samples where rays cross
    occupied space, 35.6 dB against the full render at s = 2 on lego). Everything else is the model's."""

    def __init__(self, model, stride: int):
        self.base, self.stride = model, int(stride)

    def __getattr__(self, name):
        if name == "base":  # (not set yet: no recursion)
            raise AttributeError(name)
        return getattr(self.base, name)

    def candidates(self, o, d, key=None, index=None):
        """As model.candidates: t_start, t_end, cand [R, K / s] or shaped like `index` (int [R, W])."""
        s = self.stride
        if index is None:
            k = -(-self.base.cfg.sampler.march_steps // s)
            index = jnp.broadcast_to(jnp.arange(k, dtype=jnp.int32)[None, :], (o.shape[0], k))
        t0, _, cand = self.base.candidates(o, d, key, s * index)
        _, t1, _ = self.base.candidates(o, d, key, s * index + (s - 1))
        return t0, t1, cand


def coarser(renderer: WavefrontRenderer, stride: int) -> WavefrontRenderer:
    """A wavefront renderer like `renderer` whose rays march with a `stride` times longer step
    (CoarseMarch), sharing renderer's cached empty-space distance field."""
    r = type(renderer)(CoarseMarch(renderer.model, stride), renderer.chunk)
    r.empty_distance = renderer.empty_distance
    return r
