"""The shear-warp backend (Lacroute 1995): factorization, RLE classified volume, RLE image, warp (Numba)."""
