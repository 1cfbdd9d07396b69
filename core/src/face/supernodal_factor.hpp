// The face solver's linear solve: a sparse lower Cholesky factor of the (already permuted) system
// matrix, A = L Lᵀ, copied in single precision into supernodes, and the forward and backward
// substitutions over it with x, y and z of a node in one SSE vector (two nodes in one AVX register
// in the loops over the rows below a supernode, where the CPU has AVX).
//
// Supernodes are runs of consecutive columns whose structure below the run is the same
// (fundamental supernodes; at level 1, 82 % of the 94k entries are in runs of 4 columns or more).
// A supernode of w columns starting at column c0 stores its strictly lower w × w diagonal block
// and the dense block of its m rows below, both row-major, with one row index per row (16-bit
// where n ≤ 65536) instead of one per entry. The forward solve then takes a dot product of each
// row with the supernode's w unknowns (in L1) and updates one z per row; the backward solve
// accumulates four columns at a time from the same rows. Compared with one scatter
// per entry, this halves the instructions per entry and the index traffic; the float values keep
// the factor (level 1: 0.4 MB) within one core's 512 KiB L2 cache. It solves for corrections
// only (iterative refinement: the residual is computed in double, face_solver.cpp), so its
// rounding changes how fast an iteration converges, not where it converges to.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace lipsync::face::detail {

/// Four floats in one SSE register (x, y, z, unused): a node's correction in the float solve.
typedef float Float4 __attribute__((vector_size(16)));  // NOLINT(modernize-use-using)

struct SupernodalFactor {
  struct Supernode {
    int first_column, width;
    int row_begin, row_end;  // rows below the supernode: row_index[row_begin, row_end)
    int diagonal_offset;     // w(w−1)/2 values: row c's entries left of the diagonal, c = 1 … w−1
    int block_offset;        // (row_end − row_begin) × w values, row-major
  };
  std::vector<Supernode> supernodes;
  std::vector<std::uint16_t> row16;  // used when n ≤ 65536
  std::vector<std::uint32_t> row32;  // otherwise
  std::vector<float> value;
  std::vector<float> inverse_diagonal;
  bool use_avx = false;  // the rows' loops in 256-bit AVX (chosen in build() where the CPU has it)

  /// From the n × n factor L in compressed columns, diagonal first, rows ascending (Eigen's
  /// SimplicialLLT): `outer` has n + 1 column starts, `inner` the row of each value in `l`.
  void build(std::size_t n, const int* outer, const int* inner, const double* l);

  /// Solves L Lᵀ x = b for three right-hand sides at once: z holds b on entry (one Float4 per
  /// node, in the factor's order) and x on return.
  void solve_in_place(Float4* z) const;

 private:
  template <typename Kernels, typename Index>
  void solve(const Index* row, Float4* z) const;
};

}  // namespace lipsync::face::detail
