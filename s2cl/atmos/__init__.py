"""The atmosphere: the 6S look-up table (format, builder, validation), run-time terms, the band-effective
correction and its residuals.
"""
