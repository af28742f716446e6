"""The sensor: bands, spectral response functions, the noise model, and band variants."""
