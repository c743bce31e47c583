//! Real spherical harmonics of degree 0..3 as the 3DGS rasterizer evaluates them
//! (computeColorFromSH in graphdeco-inria's forward.cu, constants of utils/sh_utils.py).
#pragma once

#if defined(__CUDACC__) || defined(__HIPCC__)
#define GEN4D_SH_HD __host__ __device__
#else
#define GEN4D_SH_HD
#endif

namespace gen4d::gaussians {

//! Colour of one splat seen along the unit direction (x, y, z): max(SH(d) + 0.5, 0) per channel.
//! `sh` holds the splat's (degree + 1)^2 coefficients coefficient-major (sh[k * 3 + c],
//! Splats.hpp's layout); degree is 0..3. Single precision, the rasterizer's order of operations.
GEN4D_SH_HD inline void sh_color(int degree, const float* sh, float x, float y, float z,
                                 float rgb[3]) {
  constexpr float c0 = 0.28209479177387814f;
  constexpr float c1 = 0.4886025119029199f;
  constexpr float c2[5] = {1.0925484305920792f, -1.0925484305920792f, 0.31539156525252005f,
                           -1.0925484305920792f, 0.5462742152960396f};
  constexpr float c3[7] = {-0.5900435899266435f, 2.890611442640554f,   -0.4570457994644658f,
                           0.3731763325901154f,  -0.4570457994644658f, 1.445305721320277f,
                           -0.5900435899266435f};
  for (int c = 0; c < 3; ++c) {
    const float* s = sh + c;  // coefficient k of this channel: s[3 * k]
    float r = c0 * s[0];
    if (degree > 0) {
      r = r - c1 * y * s[3] + c1 * z * s[6] - c1 * x * s[9];
      if (degree > 1) {
        const float xx = x * x, yy = y * y, zz = z * z;
        const float xy = x * y, yz = y * z, xz = x * z;
        r = r + c2[0] * xy * s[12] + c2[1] * yz * s[15] + c2[2] * (2.0f * zz - xx - yy) * s[18] +
            c2[3] * xz * s[21] + c2[4] * (xx - yy) * s[24];
        if (degree > 2) {
          r = r + c3[0] * y * (3.0f * xx - yy) * s[27] + c3[1] * xy * z * s[30] +
              c3[2] * y * (4.0f * zz - xx - yy) * s[33] +
              c3[3] * z * (2.0f * zz - 3.0f * xx - 3.0f * yy) * s[36] +
              c3[4] * x * (4.0f * zz - xx - yy) * s[39] + c3[5] * z * (xx - yy) * s[42] +
              c3[6] * x * (xx - 3.0f * yy) * s[45];
        }
      }
    }
    r += 0.5f;
    rgb[c] = r > 0.0f ? r : 0.0f;
  }
}

}  // namespace gen4d::gaussians
