// Draw-unit sort benchmark: sort time, state_changes and launches for
// --sort none|material|depth|gray|key at 10^3..10^6 units, plus the Gray queue's incremental
// update of one unit against a full re-sort.
//
//   strata_sort_bench [--benchmark_filter=...] [--benchmark_format=json|csv] ...
//
// State distributions (16 state bits):
//   scene:   12 materials, each fixing an effect (one of 4, one-hot), textured, an alpha mode
//            (opaque / mask / blend) and a kernel variant (one of 6, one-hot); per unit two-sided
//            (p = 0.3) and two rare flags (p = 0.1, 0.05). At most a few hundred distinct states.
//   uniform: all 16 bits independent, p = 0.5 (up to 65536 distinct states; the worst case).
//   wide:    40 bits: each material fixes a random 24-bit pattern, plus 16 per-unit flags with
//            p = 0.5, 0.25, 0.17, ... (sparse codes too wide for one bucket per rank).
#include <benchmark/benchmark.h>

#include <random>
#include <string>
#include <vector>

#include "engine/features/draw_sort.h"

namespace {

using namespace strata;

enum class Dist { Scene, Uniform, Wide };
const char* distName(Dist d) {
  return d == Dist::Scene ? "scene" : d == Dist::Uniform ? "uniform" : "wide";
}

std::vector<DrawUnit> makeUnits(size_t n, Dist dist, uint64_t seed = 42) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f), pos(-100.0f, 100.0f);
  constexpr int kMaterials = 12;
  struct Mat {
    uint64_t state;
    bool blend;
  };
  std::vector<Mat> mats(kMaterials);
  for (Mat& m : mats) {
    m.state = 0;
    m.state |= 1ull << (rng() % 4);             // effect, bits 0..3
    if (u01(rng) < 0.6f) m.state |= 1ull << 4;  // textured
    const int alpha = int(rng() % 3);           // opaque / mask / blend
    if (alpha == 1) m.state |= 1ull << 7;
    m.blend = alpha == 2;
    if (m.blend) m.state |= 1ull << 6;
    m.state |= 1ull << (8 + rng() % 6);  // kernel variant, bits 8..13
  }
  std::vector<uint64_t> wide_mats(kMaterials);
  for (uint64_t& w : wide_mats) w = rng() & 0xffffff;
  // Material popularity falls off (a few materials cover most units).
  std::discrete_distribution<int> pick({30, 20, 12, 9, 7, 6, 5, 4, 3, 2, 1, 1});
  std::vector<DrawUnit> units(n);
  for (size_t i = 0; i < n; ++i) {
    DrawUnit& u = units[i];
    u.first_triangle = uint32_t(i * 64);
    u.triangle_count = 64;
    u.object_id = uint32_t(i);
    u.center = {pos(rng), pos(rng), pos(rng)};
    if (dist == Dist::Scene) {
      const int m = pick(rng);
      u.material = uint32_t(m);
      u.state = mats[m].state | (1ull << 20);       // bit 20: shared by all (set once)
      if (u01(rng) < 0.3f) u.state |= 1ull << 5;    // two-sided
      if (u01(rng) < 0.1f) u.state |= 1ull << 14;   // rare flag
      if (u01(rng) < 0.05f) u.state |= 1ull << 15;  // rarer flag
      u.transparent = mats[m].blend;
    } else if (dist == Dist::Uniform) {
      u.material = uint32_t(rng() % kMaterials);
      u.state = rng() & 0xffff;
      u.transparent = (u.state >> 6) & 1;
    } else {
      const int m = pick(rng);
      u.material = uint32_t(m);
      u.state = wide_mats[m];
      for (int k = 0; k < 16; ++k)
        if (u01(rng) < 0.5f / float(k + 1)) u.state |= 1ull << (24 + k);
      u.transparent = (u.state >> 24) & 1;
    }
  }
  return units;
}

void runSort(DrawSorter& sorter, DrawSort method, const std::vector<DrawUnit>& units,
             const DrawSortView& view, std::vector<uint32_t>& order) {
  switch (method) {
    case DrawSort::None:
      sorter.sortNone(units, order);
      break;
    case DrawSort::Material:
      sorter.sortMaterial(units, order);
      break;
    case DrawSort::Depth:
      sorter.sortDepth(units, view, order);
      break;
    case DrawSort::Gray:
      sorter.sortGray(units, order);
      break;
    case DrawSort::Key:
      sorter.sortKey(units, view, order);
      break;
  }
}

void BM_Sort(benchmark::State& state, DrawSort method, Dist dist, bool chained) {
  const size_t n = size_t(state.range(0));
  const std::vector<DrawUnit> units = makeUnits(n, dist);
  const DrawSortView view{{0.0f, 0.0f, 300.0f}, {0.0f, 0.0f, -1.0f}};
  DrawSorter sorter;
  sorter.gray_chained_buckets = chained;
  std::vector<uint32_t> order;
  runSort(sorter, method, units, view, order);  // warm the scratch buffers
  for (auto _ : state) {
    runSort(sorter, method, units, view, order);
    benchmark::DoNotOptimize(order.data());
    benchmark::ClobberMemory();
  }
  const DrawSortStats s = measureDrawOrder(units, order);
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(n));
  state.counters["state_changes"] = double(s.state_changes);
  state.counters["launches"] = double(s.launches);
  state.counters["material_changes"] = double(s.material_changes);
  state.counters["bits_per_step"] = n > 1 ? double(s.state_changes) / double(n - 1) : 0.0;
  state.counters["ns_per_unit"] = benchmark::Counter(
      double(n), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

// One unit's state changes (toggle two-sided, or a rare flag), then the order must be current:
// the Gray queue updates in place, the packed-key peer re-sorts everything.
void BM_GrayQueueChange(benchmark::State& state) {
  const size_t n = size_t(state.range(0));
  const std::vector<DrawUnit> units = makeUnits(n, Dist::Scene);
  std::vector<uint64_t> states;
  for (const DrawUnit& u : units) states.push_back(u.state);
  GrayQueue q;
  q.build(states);
  std::mt19937_64 rng(7);
  const int bits[] = {5, 14, 15};
  for (auto _ : state) {
    const GrayQueue::Handle h = GrayQueue::Handle(rng() % n);
    q.flipBit(h, bits[rng() % 3]);
  }
  state.counters["rank_refreshes"] = double(q.rankRefreshes());
}

void BM_GrayQueueAddRemove(benchmark::State& state) {
  const size_t n = size_t(state.range(0));
  const std::vector<DrawUnit> units = makeUnits(n + 1, Dist::Scene);
  std::vector<uint64_t> states;
  for (size_t i = 0; i < n; ++i) states.push_back(units[i].state);
  GrayQueue q;
  q.build(states);
  for (auto _ : state) {
    const GrayQueue::Handle h = q.add(units[n].state);
    q.remove(h);
  }
}

void BM_KeyResortAfterChange(benchmark::State& state) {
  const size_t n = size_t(state.range(0));
  std::vector<DrawUnit> units = makeUnits(n, Dist::Scene);
  const DrawSortView view{{0.0f, 0.0f, 300.0f}, {0.0f, 0.0f, -1.0f}};
  DrawSorter sorter;
  std::vector<uint32_t> order;
  std::mt19937_64 rng(7);
  for (auto _ : state) {
    units[rng() % n].state ^= 1ull << 5;
    sorter.sortKey(units, view, order);
    benchmark::DoNotOptimize(order.data());
  }
}

}  // namespace

int main(int argc, char** argv) {
  for (Dist dist : {Dist::Scene, Dist::Uniform, Dist::Wide})
    for (DrawSort method :
         {DrawSort::None, DrawSort::Material, DrawSort::Depth, DrawSort::Gray, DrawSort::Key}) {
      const std::string name = std::string("sort/") + distName(dist) + "/" + drawSortName(method);
      benchmark::RegisterBenchmark(name.c_str(), BM_Sort, method, dist, false)
          ->RangeMultiplier(10)
          ->Range(1000, 1000000)
          ->Unit(benchmark::kMicrosecond);
      if (method == DrawSort::Gray)  // the patent's literal linked-chain buckets
        benchmark::RegisterBenchmark((name + "_chained").c_str(), BM_Sort, method, dist, true)
            ->RangeMultiplier(10)
            ->Range(1000, 1000000)
            ->Unit(benchmark::kMicrosecond);
    }
  benchmark::RegisterBenchmark("incremental/gray_queue_flip", BM_GrayQueueChange)
      ->RangeMultiplier(10)
      ->Range(1000, 1000000)
      ->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("incremental/gray_queue_add_remove", BM_GrayQueueAddRemove)
      ->RangeMultiplier(10)
      ->Range(1000, 1000000)
      ->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("incremental/key_resort", BM_KeyResortAfterChange)
      ->RangeMultiplier(10)
      ->Range(1000, 1000000)
      ->Unit(benchmark::kMicrosecond);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
