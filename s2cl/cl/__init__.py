"""OpenCL plumbing: device choice, context, queue and builds (runtime), templates, kernel argument specs, vector
types, device buffers and the device math helpers' host side.
"""
