"""Radiosity in NumPy: a scene cut into patches, form factors, the interreflection solve and its images.

The references for the interreflection effects the renderer shows (concave corners, grooves, the
spherical cap, colour bleeding) and the forward models of the algorithms that undo them.  This
layer sits above :mod:`pbrbench.scene` (it builds patches from a scene spec) and below
:mod:`pbrbench.render` (whose proofs compare renders with it):

- :mod:`~pbrbench.radiosity.patches`: planar patches of a scene, their geometry and albedo;
- :mod:`~pbrbench.radiosity.raycast` and :mod:`~pbrbench.radiosity.form_factor_matrix`: the
  patch-to-patch form factors with occlusion;
- :mod:`~pbrbench.radiosity.solver`: the radiosity system ``B = E + rho F B``;
- :mod:`~pbrbench.radiosity.image`: patch radiosities rendered into the camera;
- :mod:`~pbrbench.radiosity.forward_models`: the per-scene models the tasks use (cached);
- :mod:`~pbrbench.radiosity.concave_cap`, :mod:`~pbrbench.radiosity.groove_profile`: closed forms
  and profile solves of the two classical concave shapes.

The closed-form irradiance and form factors without occlusion stay in :mod:`pbrbench.shading`.
"""
