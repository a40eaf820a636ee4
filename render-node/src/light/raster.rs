//! CPU reference rasteriser: the same triangles, depth test and pixel-centre rules as the GPU, for pixel-wise comparison.
