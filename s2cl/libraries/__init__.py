"""Spectral libraries: the SpectralLibrary type and its file formats, the built-in ones (PROSAIL, USGS minerals,
flat targets) and their registry.
"""
