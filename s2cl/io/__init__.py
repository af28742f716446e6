"""Where outputs go and what a run may use: atomic files, output folders and their lock, the memory and disk
budget, CSV tables, the cache folder, PNGs.
"""
