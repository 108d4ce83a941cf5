// Study for docs/notebook/benchmarks-history.md ("What 1 ms at 1M would still need"): a
// cluster-pair scheme (GROMACS-style: clusters of C particles, every pair of
// two clusters whose bounding boxes come within the support is evaluated)
// against the pairs within the support. A jittered cubic lattice (spacing 1,
// +-0.1), support 4 (h = 2 dx), interior clusters only; clusters cut from the
// solver's sort order (cells of the support, 4 slabs along x, x-fastest) and
// from compact lattice blocks.
//   g++ -O2 tools/cluster_pairs.cpp -o /tmp/cluster_pairs && /tmp/cluster_pairs
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>
struct P { float x, y, z; };
int main() {
  const int L = 40; const float s = 4.0f, s2 = s * s;
  std::mt19937 rng(1); std::uniform_real_distribution<float> U(-0.1f, 0.1f);
  std::vector<P> p;
  for (int z = 0; z < L; ++z) for (int y = 0; y < L; ++y) for (int x = 0; x < L; ++x)
    p.push_back({x + 0.5f + U(rng), y + 0.5f + U(rng), z + 0.5f + U(rng)});
  const int n = p.size();
  auto study = [&](const char* name, std::vector<int> order, int C) {
    // clusters of C consecutive entries of order; bounding boxes
    int nc = n / C;
    std::vector<P> lo(nc), hi(nc);
    for (int c = 0; c < nc; ++c) {
      lo[c] = hi[c] = p[order[c * C]];
      for (int k = 1; k < C; ++k) { P q = p[order[c * C + k]];
        lo[c].x = std::min(lo[c].x, q.x); lo[c].y = std::min(lo[c].y, q.y); lo[c].z = std::min(lo[c].z, q.z);
        hi[c].x = std::max(hi[c].x, q.x); hi[c].y = std::max(hi[c].y, q.y); hi[c].z = std::max(hi[c].z, q.z); }
    }
    double eval = 0, real = 0, ext = 0; int counted = 0;
    for (int a = 0; a < nc; ++a) {
      // interior clusters only
      if (lo[a].x < 6 || lo[a].y < 6 || lo[a].z < 6 || hi[a].x > L - 6 || hi[a].y > L - 6 || hi[a].z > L - 6) continue;
      ++counted; ext += (hi[a].x - lo[a].x) + (hi[a].y - lo[a].y) + (hi[a].z - lo[a].z);
      for (int b = 0; b < nc; ++b) {
        float dx = std::max(0.0f, std::max(lo[b].x - hi[a].x, lo[a].x - hi[b].x));
        float dy = std::max(0.0f, std::max(lo[b].y - hi[a].y, lo[a].y - hi[b].y));
        float dz = std::max(0.0f, std::max(lo[b].z - hi[a].z, lo[a].z - hi[b].z));
        if (dx * dx + dy * dy + dz * dz >= s2) continue;
        eval += C * C;
        for (int i = 0; i < C; ++i) for (int j = 0; j < C; ++j) {
          if (a == b && i == j) continue;
          P u = p[order[a * C + i]], v = p[order[b * C + j]];
          float r2 = (u.x-v.x)*(u.x-v.x)+(u.y-v.y)*(u.y-v.y)+(u.z-v.z)*(u.z-v.z);
          real += r2 < s2;
        }
      }
    }
    printf("%-34s C=%d: real/evaluated %.2f, evaluated per particle %.0f, real %.0f, mean bbox extent %.2f\n", name, C,
           real / eval, eval / counted / C, real / counted / C, ext / counted / 3);
  };
  // (A) sphray order: cells of s, 4 slabs along x, x-fastest keys; stable by index within a slab
  const int nx = (L + 3) / 4;
  std::vector<int> idx(n); for (int i = 0; i < n; ++i) idx[i] = i;
  auto key = [&](int i) { int cx = int(p[i].x / s), cy = int(p[i].y / s), cz = int(p[i].z / s);
    int sub = std::min(3, int((p[i].x - cx * s) / (s / 4)));
    return ((cz * nx + cy) * nx + cx) * 4 + sub; };
  std::vector<int> a = idx; std::stable_sort(a.begin(), a.end(), [&](int i, int j) { return key(i) < key(j); });
  // (B) compact blocks: 2x2x2 lattice blocks in Morton-ish order (block key, then in-block)
  auto bkey = [&](int i, int b) { int x = int(p[i].x) / b, y = int(p[i].y) / b, z = int(p[i].z) / b; return (z * L + y) * L + x; };
  std::vector<int> b4 = idx; std::stable_sort(b4.begin(), b4.end(), [&](int i, int j) { return bkey(i, 4) < bkey(j, 4); });
  // within a 4x4x4 block, 2x2x2 sub-blocks first
  std::vector<int> b42 = idx; std::stable_sort(b42.begin(), b42.end(), [&](int i, int j) {
    int ki = bkey(i, 4), kj = bkey(j, 4); if (ki != kj) return ki < kj; return bkey(i, 2) < bkey(j, 2); });
  study("sphray sort order", a, 8);
  study("sphray sort order", a, 4);
  study("4x4x4 blocks, 2x2x2 inside", b42, 8);
  study("4x4x4 blocks, 2x2x2 inside", b42, 4);
  study("4x4x4 blocks", b4, 32);
}
