"""The forward chain on the device: resampling, the radiometric stage (noise, quantise, calibrate, correct),
library and streamed simulations, image cubes, datasets, the host Philox noise.
"""
