// The supernodal factor's construction from Eigen's L and its two substitutions; the layout and
// why it is fast are in supernodal_factor.hpp.
#include "face/supernodal_factor.hpp"

#include <algorithm>
#include <bit>
#include <cstring>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define LIPSYNC_FACE_AVX 1
#endif

namespace lipsync::face::detail {

namespace {

// The substitutions' inner kernels, declared `inline` (as they were implicitly when they were
// members defined in a class): GCC gives a function not declared inline a smaller inlining budget,
// and `dot` would then stay a call per row of both substitutions.

// Four consecutive values (unaligned) and one of them in all lanes (shufps).
inline Float4 load4(const float* p) {
  Float4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <int lane>
inline Float4 splat(Float4 v) {
  return Float4{v[lane], v[lane], v[lane], v[lane]};
}

// Σ o[c] · zs[c], c < w.
inline Float4 dot(const float* o, const Float4* zs, int w) {
  Float4 a = {0, 0, 0, 0}, b = {0, 0, 0, 0};
  int c = 0;
  for (; c + 4 <= w; c += 4) {
    const Float4 v = load4(o + c);
    a += splat<0>(v) * zs[c];
    b += splat<1>(v) * zs[c + 1];
    a += splat<2>(v) * zs[c + 2];
    b += splat<3>(v) * zs[c + 3];
  }
  for (; c < w; ++c) a += o[c] * zs[c];
  return a + b;
}

// The two loops over a supernode's rows below its diagonal block, where the factor's entries are
// (82 % of them at level 1), in two builds: SSE (any x86-64) and AVX, which holds two nodes' x, y, z
// in one 256-bit register and so halves the multiplies, adds and shuffles per entry. The AVX loops
// do the same float operations in the same order on every value (no fused multiply–add; `dot`'s
// two accumulators are the register's halves), so both give the same bits.
struct SseKernels {
  // z[row[k]] −= Σ_c o[k][c] · zs[c] for the supernode's rows k (forward substitution).
  template <typename Index>
  static void subtract_rows(const Index* row, int begin, int end, const float* o, int w, const Float4* zs, Float4* z) {
    for (int k = begin; k < end; ++k, o += w) z[row[k]] -= dot(o, zs, w);
  }
  // zs[c] −= Σ_k block[k][c] · z[row[k]] for the columns c in whole groups of four (backward
  // substitution); returns how many columns it did.
  template <typename Index>
  static int subtract_columns(const Index* row, int begin, int end, const float* block, int w, const Float4* z,
                              Float4* zs) {
    int c = 0;
    for (; c + 4 <= w; c += 4) {
      Float4 a0 = {0, 0, 0, 0}, a1 = a0, a2 = a0, a3 = a0;
      const float* o = block + c;
      for (int k = begin; k < end; ++k, o += w) {
        const Float4 zr = z[row[k]], v = load4(o);
        a0 += splat<0>(v) * zr;
        a1 += splat<1>(v) * zr;
        a2 += splat<2>(v) * zr;
        a3 += splat<3>(v) * zr;
      }
      zs[c] -= a0;
      zs[c + 1] -= a1;
      zs[c + 2] -= a2;
      zs[c + 3] -= a3;
    }
    return c;
  }
};

#if defined(LIPSYNC_FACE_AVX)
struct AvxKernels {
  __attribute__((target("avx"))) static __m256 load_pair(const Float4* z) {
    return _mm256_loadu_ps(reinterpret_cast<const float*>(z));
  }
  // Four consecutive values in both halves.
  __attribute__((target("avx"))) static __m256 load4_twice(const float* o) {
    return _mm256_broadcast_ps(reinterpret_cast<const __m128*>(o));
  }
  __attribute__((target("avx"))) static Float4 low(__m256 v) {
    return std::bit_cast<Float4>(_mm256_castps256_ps128(v));
  }
  __attribute__((target("avx"))) static Float4 high(__m256 v) {
    return std::bit_cast<Float4>(_mm256_extractf128_ps(v, 1));
  }

  template <typename Index>
  __attribute__((target("avx"))) static void subtract_rows(const Index* row, int begin, int end, const float* o, int w,
                                                           const Float4* zs, Float4* z) {
    const __m256i even = _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1), odd = _mm256_setr_epi32(2, 2, 2, 2, 3, 3, 3, 3);
    for (int k = begin; k < end; ++k, o += w) {
      __m256 ab = _mm256_setzero_ps();  // dot's a (even columns) and b (odd columns)
      int c = 0;
      for (; c + 4 <= w; c += 4) {
        const __m256 v = load4_twice(o + c);
        ab = _mm256_add_ps(ab, _mm256_mul_ps(_mm256_permutevar_ps(v, even), load_pair(zs + c)));
        ab = _mm256_add_ps(ab, _mm256_mul_ps(_mm256_permutevar_ps(v, odd), load_pair(zs + c + 2)));
      }
      Float4 a = low(ab);
      for (; c < w; ++c) a += o[c] * zs[c];
      z[row[k]] -= a + high(ab);
    }
  }

  template <typename Index>
  __attribute__((target("avx"))) static int subtract_columns(const Index* row, int begin, int end, const float* block,
                                                             int w, const Float4* z, Float4* zs) {
    int c = 0;
    for (; c + 8 <= w; c += 8) {  // columns (c, c + 4), (c + 1, c + 5), … in the halves
      __m256 a04 = _mm256_setzero_ps(), a15 = a04, a26 = a04, a37 = a04;
      const float* o = block + c;
      for (int k = begin; k < end; ++k, o += w) {
        const __m256 zr = load4_twice(reinterpret_cast<const float*>(z + row[k])), v = _mm256_loadu_ps(o);
        a04 = _mm256_add_ps(a04, _mm256_mul_ps(_mm256_permute_ps(v, 0x00), zr));
        a15 = _mm256_add_ps(a15, _mm256_mul_ps(_mm256_permute_ps(v, 0x55), zr));
        a26 = _mm256_add_ps(a26, _mm256_mul_ps(_mm256_permute_ps(v, 0xaa), zr));
        a37 = _mm256_add_ps(a37, _mm256_mul_ps(_mm256_permute_ps(v, 0xff), zr));
      }
      zs[c] -= low(a04);
      zs[c + 1] -= low(a15);
      zs[c + 2] -= low(a26);
      zs[c + 3] -= low(a37);
      zs[c + 4] -= high(a04);
      zs[c + 5] -= high(a15);
      zs[c + 6] -= high(a26);
      zs[c + 7] -= high(a37);
    }
    if (c + 4 <= w) {  // columns (c, c + 1), (c + 2, c + 3)
      const __m256i first = _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1),
                    second = _mm256_setr_epi32(2, 2, 2, 2, 3, 3, 3, 3);
      __m256 a01 = _mm256_setzero_ps(), a23 = a01;
      const float* o = block + c;
      for (int k = begin; k < end; ++k, o += w) {
        const __m256 zr = load4_twice(reinterpret_cast<const float*>(z + row[k])), v = load4_twice(o);
        a01 = _mm256_add_ps(a01, _mm256_mul_ps(_mm256_permutevar_ps(v, first), zr));
        a23 = _mm256_add_ps(a23, _mm256_mul_ps(_mm256_permutevar_ps(v, second), zr));
      }
      zs[c] -= low(a01);
      zs[c + 1] -= high(a01);
      zs[c + 2] -= low(a23);
      zs[c + 3] -= high(a23);
      c += 4;
    }
    return c;
  }
};
#endif

}  // namespace

void SupernodalFactor::build(std::size_t n, const int* outer, const int* inner, const double* l) {
  const bool small = n <= 65536;
#if defined(LIPSYNC_FACE_AVX)
  use_avx = __builtin_cpu_supports("avx") != 0;
#endif
  inverse_diagonal.resize(n);
  for (std::size_t j = 0; j < n; ++j) inverse_diagonal[j] = static_cast<float>(1.0 / l[outer[j]]);
  // Column j + 1 continues j's supernode when struct(j) = {j + 1} ∪ struct(j + 1).
  auto continues = [&](std::size_t j) {
    const int b0 = outer[j] + 1, e0 = outer[j + 1], b1 = outer[j + 1] + 1, e1 = outer[j + 2];
    if (e0 - b0 != e1 - b1 + 1 || inner[b0] != static_cast<int>(j + 1)) return false;
    return std::equal(inner + b0 + 1, inner + e0, inner + b1);
  };
  for (std::size_t c0 = 0; c0 < n;) {
    std::size_t w = 1;
    while (c0 + w < n && continues(c0 + w - 1)) ++w;
    Supernode s{};
    s.first_column = static_cast<int>(c0);
    s.width = static_cast<int>(w);
    s.diagonal_offset = static_cast<int>(value.size());
    for (std::size_t c2 = 1; c2 < w; ++c2)
      for (std::size_t c = 0; c < c2; ++c) value.push_back(static_cast<float>(l[outer[c0 + c] + (c2 - c)]));
    // Rows below: those of the last column, after its diagonal.
    const int last = outer[c0 + w - 1];
    s.row_begin = static_cast<int>(small ? row16.size() : row32.size());
    s.block_offset = static_cast<int>(value.size());
    for (int p = last + 1; p < outer[c0 + w]; ++p) {
      if (small)
        row16.push_back(static_cast<std::uint16_t>(inner[p]));
      else
        row32.push_back(static_cast<std::uint32_t>(inner[p]));
      const int k = p - (last + 1);  // position among the rows below
      for (std::size_t c = 0; c < w; ++c)
        value.push_back(static_cast<float>(l[outer[c0 + c] + static_cast<int>(w - c) + k]));
    }
    s.row_end = static_cast<int>(small ? row16.size() : row32.size());
    supernodes.push_back(s);
    c0 += w;
  }
}

template <typename Kernels, typename Index>
void SupernodalFactor::solve(const Index* row, Float4* z) const {
  const float* inv = inverse_diagonal.data();
  for (const Supernode& s : supernodes) {  // L y = b
    Float4* zs = z + s.first_column;
    const int w = s.width;
    const float* d = value.data() + s.diagonal_offset;
    for (int c = 0; c < w; d += c, ++c) zs[c] = (zs[c] - dot(d, zs, c)) * inv[s.first_column + c];
    const float* o = value.data() + s.block_offset;
    if (w == 1) {  // a single column: a plain scatter
      const Float4 z0 = zs[0];
      for (int k = s.row_begin; k < s.row_end; ++k) z[row[k]] -= *o++ * z0;
      continue;
    }
    Kernels::subtract_rows(row, s.row_begin, s.row_end, o, w, zs, z);
  }
  for (auto it = supernodes.rbegin(); it != supernodes.rend(); ++it) {  // Lᵀ x = y
    const Supernode& s = *it;
    Float4* zs = z + s.first_column;
    const int w = s.width;
    const float* block = value.data() + s.block_offset;
    int c = Kernels::subtract_columns(row, s.row_begin, s.row_end, block, w, z, zs);
    if (c < w) {  // the last one to three columns
      Float4 a0 = {0, 0, 0, 0}, a1 = a0, a2 = a0;
      const float* o = block + c;
      const int rest = w - c;
      for (int k = s.row_begin; k < s.row_end; ++k, o += w) {
        const Float4 zr = z[row[k]];
        a0 += o[0] * zr;
        if (rest > 1) a1 += o[1] * zr;
        if (rest > 2) a2 += o[2] * zr;
      }
      zs[c] -= a0;
      if (rest > 1) zs[c + 1] -= a1;
      if (rest > 2) zs[c + 2] -= a2;
    }
    // The diagonal block, by rows from the last: finish unknown c, then remove it from those left of it.
    for (c = w - 1; c >= 0; --c) {
      const Float4 zc = zs[c] * inv[s.first_column + c];
      zs[c] = zc;
      const float* d = value.data() + s.diagonal_offset + c * (c - 1) / 2;
      for (int c2 = 0; c2 < c; ++c2) zs[c2] -= d[c2] * zc;
    }
  }
}

void SupernodalFactor::solve_in_place(Float4* z) const {
#if defined(LIPSYNC_FACE_AVX)
  if (use_avx) {
    if (row32.empty())
      solve<AvxKernels>(row16.data(), z);
    else
      solve<AvxKernels>(row32.data(), z);
    return;
  }
#endif
  if (row32.empty())
    solve<SseKernels>(row16.data(), z);
  else
    solve<SseKernels>(row32.data(), z);
}

}  // namespace lipsync::face::detail
