"""Inverse rendering: shape and albedo that explain the images with Mitsuba's full light transport.

Unlike :mod:`pbrbench.infer` (NumPy/SciPy only, local image models), this package renders: it
needs a differentiable Mitsuba variant (``llvm_ad_rgb`` on the CPU, ``cuda_ad_rgb`` on a GPU),
chosen safely by :func:`pbrbench.render.variant.mitsuba` when a method is *called*; importing the
package imports neither Mitsuba nor Dr.Jit.

Methods (:data:`METHODS`; the photometric-stereo task registers each as ``inverse:<name>`` with
its scene interface, ``docs/inverse.md``):

- ``"nicolet2021"``: :func:`inverse_rendering_nicolet2021`, a height field on the image grid and a
  per-pixel albedo fitted by Adam on a Sobolev-preconditioned gradient (large steps, Nicolet et
  al. 2021) of the image loss of Mitsuba's path-traced renders, the residual back-propagated
  through path replay backpropagation (Vicini et al. 2021) of the direct light.

Signature: ``fn(images (K, H, W), lights (K, 3), *, mask, scene, max_depth, seed, <options>)`` with
``scene`` the :class:`~pbrbench.scene.spec.SceneSpec` of the images (its camera, light set and
lateral extent are used, never the object's geometry or material) and ``max_depth`` the light
transport of the images (-1 full interreflection, 2 direct light).

Modules: :mod:`.heightfield` (mesh on the pixel-corner grid, priors; NumPy), :mod:`.optim` (Adam,
Sobolev preconditioner; NumPy), :mod:`.scene` (what is read from the scene description; NumPy),
:mod:`.render` (the Mitsuba scene and gradients), :mod:`.nicolet2021` (the method).
"""

from __future__ import annotations

from pbrbench.inverse.nicolet2021 import InverseRenderingResult, inverse_rendering_nicolet2021

METHODS = {"nicolet2021": inverse_rendering_nicolet2021}

__all__ = ["METHODS", "InverseRenderingResult", "inverse_rendering_nicolet2021"]
