"""Mitsuba side of :mod:`pbrbench.inverse`: the height-field scene, one light at a time, and the
gradient of the image loss with respect to the vertex heights and the albedo texture.

The scene is built with pbrbench's own builders (:func:`pbrbench.scene.mitsuba_dict.sensor_dict`
for the camera, :func:`~pbrbench.scene.mitsuba_dict.emitter_dict` for the lights), so the camera,
film (box filter, float32) and emitters are exactly those of the ground truth; the object is a
PLY mesh (:func:`~pbrbench.scene.mitsuba_dict.write_ply`) with face normals and a diffuse BSDF
whose reflectance is an ``H x W`` bitmap (nearest lookup, one texel per pixel quad).  One
emitter is in the scene; each light of the set is rendered by copying its parameters (transform,
irradiance / radiance) into it (never a zeroed light: a dark emitter still takes samples).

Gradients come from Mitsuba's path-replay backpropagation integrator (``prb``: Vicini, Speierers
& Jakob 2021), which differentiates the shading through the attached surface interactions (the
positions and face normals of the mesh) at every bounce of the full interreflection, but not
the moving visibility boundaries (cast shadows, occlusion); primary visibility is fixed anyway
(an orthographic camera looking down a height field sees every quad over its own pixel).
``prb_projective`` (Zhang et al. 2023) adds the boundary terms for a multiple of the cost.

Only :func:`pbrbench.render.variant.mitsuba` imports Mitsuba (a safely chosen AD variant).

References
----------
- D. Vicini, S. Speierers and W. Jakob, "Path replay backpropagation: differentiating light
  paths using constant memory and linear time", ACM Transactions on Graphics 40(4), 2021.
- Z. Zhang, N. Roussel and W. Jakob, "Projective sampling for differentiable rendering of
  geometry", ACM Transactions on Graphics 42(6), 2023.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

from pbrbench.inverse.heightfield import HeightField

INTEGRATORS = ("prb", "prb_projective")


def ad_mitsuba():
    """Mitsuba with a differentiable variant (``ValueError`` when only a scalar one is usable)."""
    from pbrbench.render.variant import mitsuba

    mi = mitsuba()
    if "_ad_" not in mi.variant():
        raise ValueError(f"inverse rendering needs a differentiable Mitsuba variant (llvm_ad_rgb or cuda_ad_rgb); "
                         f"this process renders with {mi.variant()}: install libLLVM >= 16 (apt-get install "
                         "libllvm19) or use a CUDA device")
    return mi


def camera_frame(camera) -> tuple[np.ndarray, np.ndarray]:
    """``(target, R)``: the film-plane origin and the rows x right, y up, z toward the camera."""
    from pbrbench.scene.geometry import camera_rotation

    return np.asarray(camera.target, float), camera_rotation(camera)


class HeightFieldScene:
    """A Mitsuba scene of one height field under one light at a time (module docstring).

    ``lights``: the emitter dicts (:func:`~pbrbench.scene.mitsuba_dict.emitter_dict` output), all of
    one kind; ``albedo`` (H, W) the initial reflectance texture.
    """

    def __init__(self, spec, hf: HeightField, z: np.ndarray, albedo: np.ndarray, lights: list[tuple[str, dict]],
                 *, max_depth: int, rr_depth: int = 5, spp: int = 4, integrator: str = "path"):
        import drjit as dr

        from pbrbench.scene.mitsuba_dict import sensor_dict, write_ply

        mi = ad_mitsuba()
        self.mi, self.dr, self.hf, self.spp = mi, dr, hf, int(spp)
        kinds = {k for k, _ in lights}
        types = {d["type"] for _, d in lights}
        if len(kinds) != 1 or len(types) != 1:
            raise ValueError(f"lights: the light set mixes kinds ({', '.join(sorted(types))}); "
                             "inverse rendering copies one light's parameters into one emitter: use lights of one type")
        self.target, self.R = camera_frame(spec.camera)
        verts = self._world(hf.vertex_heights(z))
        tmp = tempfile.mkdtemp(prefix="pbrbench-inverse-")
        path = os.path.join(tmp, "surface.ply")
        write_ply(path, verts, np.tile(self.R[2], (len(verts), 1)), hf.uv, hf.faces)
        integ = {"type": integrator, "max_depth": int(max_depth), "rr_depth": int(rr_depth)}
        tex = np.ascontiguousarray(np.flipud(albedo)[..., None], dtype=np.float32)
        d = {"type": "scene",
             "sensor": sensor_dict(mi, spec, (hf.W, hf.H), self.spp, sampler="independent"),
             "integrator": integ,
             "surface": {"type": "ply", "filename": path, "face_normals": True,
                         "bsdf": {"type": "diffuse", "reflectance": {
                             "type": "bitmap", "bitmap": mi.Bitmap(tex), "raw": True,
                             "filter_type": "nearest", "wrap_mode": "clamp"}}},
             "light": lights[0][1]}
        self.scene = mi.load_dict(d)
        os.remove(path)
        os.rmdir(tmp)
        self.params = mi.traverse(self.scene)
        self.vkey, self.akey = "surface.vertex_positions", "surface.bsdf.reflectance.data"
        # every light's own parameters, read from a stand-alone copy of its emitter
        self.light_values = []
        for _, ld in lights:
            p = mi.traverse(mi.load_dict(ld))
            self.light_values.append({f"light.{k}": p[k] for k in p.keys() if f"light.{k}" in self.params})
        self.K = len(lights)

    def _world(self, heights: np.ndarray) -> np.ndarray:
        xy = self.hf.vertex_xy
        cam = np.stack([xy[:, 0], xy[:, 1], heights], -1)
        return self.target + cam @ self.R

    def set_light(self, k: int) -> None:
        for key, v in self.light_values[k].items():
            self.params[key] = v
        self.params.update()

    def set_state(self, z: np.ndarray, albedo: np.ndarray, *, grad: bool):
        """Put heights and albedo into the scene; with ``grad`` return the two differentiable
        leaves (vertex positions, texture)."""
        mi, dr = self.mi, self.dr
        vp = mi.Float(np.ascontiguousarray(self._world(self.hf.vertex_heights(z)), dtype=np.float32).ravel())
        tex = mi.TensorXf(np.ascontiguousarray(np.flipud(albedo)[..., None], dtype=np.float32))
        if grad:
            dr.enable_grad(vp)
            dr.enable_grad(tex)
        self.params[self.vkey] = vp
        self.params[self.akey] = tex
        self.params.update()
        return vp, tex

    def render(self, k: int, seed: int, spp: int | None = None) -> np.ndarray:
        """(H, W) grey image of light ``k`` (no gradients)."""
        self.set_light(k)
        with self.dr.suspend_grad():
            img = self.mi.render(self.scene, self.params, seed=int(seed), spp=int(spp or self.spp))
        return np.array(img, dtype=np.float64).mean(axis=-1)

    def renders(self, seed: int, spp: int | None = None) -> np.ndarray:
        """(K, H, W) full-transport renders of the current state (no derivatives)."""
        return np.stack([self.render(k, seed=int(seed) * 2 * self.K + 2 * k, spp=spp) for k in range(self.K)])

    def backward(self, z, albedo, adjoint_images: np.ndarray, seed: int, spp: int, adjoint) -> tuple[np.ndarray, np.ndarray]:
        """Back-propagate the adjoint images ``dE/dR_k`` (K, H, W) through the differentiable
        render of ``adjoint`` (an integrator): ``(dE/dz (n_params,), dE/drho (H, W))``."""
        mi, dr = self.mi, self.dr
        vp, tex = self.set_state(z, albedo, grad=True)
        for k in range(self.K):
            self.set_light(k)
            g = np.repeat((adjoint_images[k] / 3.0)[..., None], 3, -1).astype(np.float32)
            adjoint.render_backward(self.scene, self.params, mi.TensorXf(g),
                                    seed=int(seed) * 2 * self.K + 2 * k + 1, spp=int(spp))
        gpos = np.array(dr.grad(vp), dtype=np.float64).reshape(-1, 3)
        galb = np.flipud(np.array(dr.grad(tex), dtype=np.float64)[..., 0])
        return self.hf.A.T @ (gpos @ self.R[2]), galb

    def full_gradients(self, z, albedo, targets, weights, seed: int, spp_grad: int | None = None):
        """The plain path-replay gradient of ``sum_k sum_p w_p (R_kp - I_kp)^2`` (every bounce
        differentiated, the scene's own integrator): ``(loss, dE/dz, dE/drho, renders)``.  Not
        used by the method (its height gradient is far noisier than the direct-light adjoint's
        in concave scenes, ``docs/inverse.md``); kept to measure that."""
        mi, dr = self.mi, self.dr
        vp, tex = self.set_state(z, albedo, grad=True)
        w = mi.TensorXf(np.ascontiguousarray(np.repeat(weights[..., None], 3, -1) / 3.0, dtype=np.float32))
        total = 0.0
        renders = np.zeros((self.K,) + weights.shape)
        for k in range(self.K):
            self.set_light(k)
            img = mi.render(self.scene, self.params, seed=int(seed) * 2 * self.K + 2 * k,
                            seed_grad=int(seed) * 2 * self.K + 2 * k + 1, spp=self.spp,
                            spp_grad=int(spp_grad or self.spp))
            t = mi.TensorXf(np.ascontiguousarray(np.repeat(targets[k][..., None], 3, -1), dtype=np.float32))
            r = img - t
            loss = dr.sum(dr.square(r) * w, axis=None)
            dr.backward(loss)
            total += float(loss.array[0])
            renders[k] = np.array(dr.detach(img), dtype=np.float64).mean(axis=-1)
        gpos = np.array(dr.grad(vp), dtype=np.float64).reshape(-1, 3)
        galb = np.flipud(np.array(dr.grad(tex), dtype=np.float64)[..., 0])
        gz = self.hf.A.T @ (gpos @ self.R[2])
        return total, gz, galb, renders
