"""float64 numpy oracles for every kernel: simple and slow on purpose.

One module per kernel family (``forward``, ``philox``, ``igrm``, …); tests and ``bench/``
compare the OpenCL results against these.
"""
