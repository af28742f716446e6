"""float64 numpy oracles for every kernel: simple and slow on purpose.

One module per kernel family (``forward``, ``igrm``, ``stages``, ``sweep``, …); tests and ``bench/``
compare the OpenCL results against these.
"""
