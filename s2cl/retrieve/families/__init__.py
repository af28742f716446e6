"""The analysis families, one module each (:mod:`s2cl.retrieve.family`): IGRM, the normalised-difference indices,
SAM, and your own formula. A module that defines ``FAMILY`` (or ``FAMILIES``) is registered."""
