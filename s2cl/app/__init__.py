"""The application layer: what a command does, in order — check the scene, size the resources, plan, build,
run, score the reference, digest and report — above the engines, which it calls and which never call it.

``checks`` (every check of a scene before work), ``analysis`` (the scene's [analysis] on a simulation),
``simulate`` (a simulation streamed to NetCDF), ``plan`` and ``sweep_budget`` (a sweep's tables, chunking and
resources), ``optimise`` (the main job: :func:`optimise` returns what the CLI prints, as data).
"""
