// Tests of the parallel clustering loop (core/clustering/parallel_clustering.h): same energy as the serial
// loop, connected clusters, valid remeshing outputs, byte-identical deterministic mode for any
// thread count, and a stress run over many small random configurations. The ThreadSanitizer
// stage of tools/run_tests.sh runs this suite (ParallelClustering*).
#include "streamcvd/core/clustering/parallel_clustering.h"
#include "streamcvd/streaming/schedule/work_space.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/fields/metric_field.h"
#include "streamcvd/core/remesh.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

#if defined(__SANITIZE_THREAD__)
// ThreadSanitizer cannot see inside the uninstrumented libtbb: the other stages run TBB on one
// thread (every test here sets kTbbThreads), and the clustering's regions run on std::threads
// (core/clustering/parallel_blocks.h).
constexpr bool kThreadSanitizer = true;
constexpr uint32_t kTbbThreads = 1;
#else
constexpr bool kThreadSanitizer = false;
constexpr uint32_t kTbbThreads = 8;  // oversubscribed on 2 cores: more interleavings
#endif

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

RemeshOptions options_for(uint32_t n, Metric metric, uint32_t threads, bool deterministic, uint32_t region_vertices) {
  RemeshOptions o;
  o.vertices = n;
  o.clustering.metric = metric;
  o.clustering.loops.threads = threads;
  o.clustering.loops.deterministic = deterministic;
  o.clustering.loops.region_vertices = region_vertices;
  return o;
}

// The guarantees of a remesh of a closed manifold (as in remesh_test.cpp): a defect-free,
// consistently oriented closed manifold with the input's Euler characteristic (or a reported
// topology change), every cluster connected.
void expect_valid_closed_output(const RemeshResult& r, const TopologyStats& input, const std::string& what) {
  SCOPED_TRACE(what);
  const TopologyStats t = compute_topology_stats(r.mesh.view());
  EXPECT_TRUE(r.checks.clusters_connected);
  EXPECT_EQ(r.placement.defect_vertices, 0u);
  EXPECT_EQ(t.nonmanifold_edges + t.nonmanifold_vertices + t.duplicate_faces + t.isolated_vertices, 0u);
  EXPECT_EQ(t.degenerate_faces, 0u);
  EXPECT_TRUE(t.consistently_oriented);
  if (!r.checks.topology_changed) {
    EXPECT_TRUE(t.closed_manifold);
    EXPECT_EQ(t.euler_characteristic, input.euler_characteristic);
  }
  EXPECT_EQ(r.checks.output_euler_characteristic, t.euler_characteristic);
}

TEST(ParallelClustering, ThreadCountResolves) {
  EXPECT_EQ(clustering_thread_count(3), 3u);
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, kTbbThreads);
  EXPECT_EQ(clustering_thread_count(0), kTbbThreads);
}

TEST(ParallelClustering, EnergyWithinATenthOfAPercentOfSerial) {
  // A different move order reaches a different local minimum: on this mesh (2000 clusters of
  // ~20 vertices) the serial loop itself spreads by ~0.1-0.2% between seeds. So each parallel
  // run must lie within 0.4% of the serial run from the same initial labels, and on average
  // over several initial samplings within 0.1% (no systematic loss). On the dragon at 20,000
  // clusters the differences are a few 0.01% (see the closing note of issue 5).
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, kTbbThreads);
  const MeshBuffers sphere = make_icosphere(6);  // 40962 vertices
  MeshStore store = MeshStore::build(sphere.view());
  const MeshView view = store.view();
  ItemData items = compute_item_data(view, {}, ram_storage(), ItemQuadrics::per_vertex);
  const ComponentBudget budget = plan_component_budget(view, items, 2000, SmallComponents::Keep, ram_storage());
  auto energy = [&](Metric metric, uint32_t threads, bool deterministic, std::vector<int32_t> labels) {
    ClusteringOptions o;
    o.metric = metric;
    o.loops.threads = threads;
    o.loops.deterministic = deterministic;
    o.loops.region_vertices = 2048;  // ~20 regions: many shared clusters
    const ClusteringReport r = minimize_clustering(view, items, labels, budget.total_clusters, o);
    EXPECT_TRUE(clusters_connected(view, labels, budget.total_clusters));
    EXPECT_EQ(r.moves_per_loop.back(), 0u);  // the constrained pass converged
    return r.final_energy;
  };
  // Pooled over thread counts and initial samplings, the mean difference has a standard error
  // of ~0.03%, so the 0.1% bound is not flaky although the default mode is not reproducible.
  // (The sanitizer build runs fewer cases and checks the per-run bound only.)
  const int seeds = kThreadSanitizer ? 2 : 4;
  const std::vector<uint32_t> thread_counts = kThreadSanitizer ? std::vector<uint32_t>{4} : std::vector<uint32_t>{2, 4};
  for (Metric metric : {Metric::I, Metric::IQ})
    for (bool deterministic : {false, true}) {
      double mean = 0, worst = 0;
      int n = 0;
      for (int seed = 0; seed < seeds; ++seed) {
        const std::vector<int32_t> initial = test::to_vector(initial_sampling(view, items, budget, 100 + seed, ram_storage()));
        const double serial = energy(metric, 1, false, initial);
        for (uint32_t threads : thread_counts) {
          const double rel = (energy(metric, threads, deterministic, initial) - serial) / serial;
          EXPECT_LT(std::abs(rel), 4e-3) << metric_name(metric) << " T=" << threads << (deterministic ? " det" : "");
          mean += rel;
          worst = std::max(worst, std::abs(rel));
          ++n;
        }
      }
      mean /= n;
      std::printf("[ energy   ] %-3s%-4s mean difference to serial %+.4f%% over %d runs (largest %.4f%%)\n",
                  metric_name(metric), deterministic ? " det" : "", 100 * mean, n, 100 * worst);
      if (!kThreadSanitizer) {
        EXPECT_LT(std::abs(mean), 1e-3) << metric_name(metric) << (deterministic ? " det" : "");
      }
    }
}

TEST(ParallelClustering, RemeshOutputsValidForEveryMetric) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, kTbbThreads);
  const MeshBuffers torus = make_torus(120, 48);  // 5760 vertices
  MeshStore store = MeshStore::build(torus.view());
  const TopologyStats input = compute_topology_stats(torus.view());
  for (Metric metric : {Metric::I, Metric::IQ, Metric::A, Metric::AQ})
    for (uint32_t threads : {2u, 4u})
      for (bool deterministic : {false, true}) {
        const std::string what = std::string(metric_name(metric)) + " T=" + std::to_string(threads) +
                                 (deterministic ? " deterministic" : "");
        // Small regions: many region borders and shared clusters, so locks and postponed edges are exercised.
        const RemeshResult r = remesh(store.view(), options_for(400, metric, threads, deterministic, 256));
        EXPECT_EQ(r.clustering.metric, metric) << what;
        EXPECT_EQ(r.clusters, 400u);
        EXPECT_EQ(r.mesh.vertex_count(), 400u) << what;
        expect_valid_closed_output(r, input, what);
      }
}

TEST(ParallelClustering, ConstrainedPassKeepsEveryClusterConnected) {
  // The clustering alone (no repair): after minimize_clustering every cluster is one piece,
  // none is empty, and the energy per loop of the constrained pass never rises.
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, kTbbThreads);
  const MeshBuffers sphere = make_icosphere(5);  // 10242 vertices
  MeshStore store = MeshStore::build(sphere.view());
  const MeshView view = store.view();
  const ItemData items = compute_item_data(view);
  const ComponentBudget budget = plan_component_budget(view, items, 600, SmallComponents::Keep, ram_storage());
  for (uint32_t threads : {2u, 8u}) {
    std::vector<int32_t> labels = test::to_vector(initial_sampling(view, items, budget, 5, ram_storage()));
    ClusteringOptions o;
    o.metric = Metric::I;
    o.loops.threads = threads;
    o.loops.region_vertices = 200;
    const ClusteringReport rep = minimize_clustering(view, items, labels, budget.total_clusters, o);
    EXPECT_TRUE(clusters_connected(view, labels, budget.total_clusters)) << threads;
    std::vector<uint32_t> size(budget.total_clusters, 0);
    for (int32_t l : labels) {
      ASSERT_GE(l, 0);
      ++size[l];
    }
    for (uint32_t s : size) EXPECT_GT(s, 0u);
    const size_t first = rep.energy_per_loop.size() - rep.constrained_loops;
    for (size_t i = first + 1; i < rep.energy_per_loop.size(); ++i)
      EXPECT_LE(rep.energy_per_loop[i], rep.energy_per_loop[i - 1] * (1 + 1e-12)) << "loop " << i;
    EXPECT_EQ(rep.moves_per_loop.back(), 0u);  // converged, not stopped by max_loops
  }
}

TEST(ParallelClustering, DeterministicModeIsByteIdenticalForAnyThreadCount) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, kTbbThreads);
  const auto dir = test::temp_dir("parallel_deterministic");
  struct Case {
    std::string name;
    MeshBuffers mesh;
    uint32_t n;
    Metric metric;
  };
  std::vector<Case> cases;
  cases.push_back({"torus-I", make_torus(120, 48), 500, Metric::I});
  cases.push_back({"sphere-IQ", make_icosphere(5), 400, Metric::IQ});
  cases.push_back({"elephant-AQ", read_mesh(test::data_path("cgal_elephant.off")), 300, Metric::AQ});
  for (const Case& c : cases) {
    MeshStore store = MeshStore::build(c.mesh.view());
    std::string reference;
    std::vector<int32_t> reference_labels;
    for (uint32_t threads : {1u, 2u, 4u, 8u}) {
      const RemeshResult r = remesh(store.view(), options_for(c.n, c.metric, threads, true, 300));
      const auto file = dir / (c.name + "_" + std::to_string(threads) + ".ply");
      write_mesh(file.string(), r.mesh.view());
      const std::string bytes = slurp(file);
      ASSERT_GT(bytes.size(), 100u);
      if (threads == 1) {
        reference = bytes;
        reference_labels = test::to_vector(r.cluster_of_vertex);
        continue;
      }
      EXPECT_TRUE(bytes == reference) << c.name << ": T=" << threads << " differs from T=1";
      EXPECT_TRUE(test::to_vector(r.cluster_of_vertex) == reference_labels) << c.name << ": T=" << threads;
    }
  }
  std::filesystem::remove_all(dir);
}

// The cleaning as the paper describes it, by BFS over each cluster's pieces: the reference the
// chunk-wise union-find of clean_clusters must reproduce.
std::vector<int32_t> reference_cleaning(const MeshView& view, const ItemData& items, std::vector<int32_t> labels,
                                        uint32_t K, uint32_t& disconnected) {
  const uint32_t V = view.vertex_count();
  std::vector<uint32_t> piece(V, UINT32_MAX);
  std::vector<double> weight;
  std::vector<int32_t> cluster;
  for (uint32_t s = 0; s < V; ++s) {
    if (labels[s] < 0 || piece[s] != UINT32_MAX) continue;
    const uint32_t id = uint32_t(weight.size());
    std::vector<uint32_t> queue = {s};
    piece[s] = id;
    double w = 0;
    for (size_t h = 0; h < queue.size(); ++h) {
      w += items.weight[queue[h]];
      for (uint32_t n : view.neighbours(queue[h]))
        if (labels[n] == labels[s] && piece[n] == UINT32_MAX) piece[n] = id, queue.push_back(n);
    }
    weight.push_back(w);
    cluster.push_back(labels[s]);
  }
  std::vector<uint32_t> best(K, UINT32_MAX), count(K, 0);
  for (uint32_t p = 0; p < weight.size(); ++p) {
    ++count[cluster[p]];
    if (best[cluster[p]] == UINT32_MAX || weight[p] > weight[best[cluster[p]]]) best[cluster[p]] = p;
  }
  disconnected = 0;
  for (uint32_t c = 0; c < K; ++c) disconnected += count[c] > 1;
  for (uint32_t v = 0; v < V; ++v)
    if (labels[v] >= 0 && best[labels[v]] != piece[v]) labels[v] = -1;
  absorb_free_vertices(view, labels);
  return labels;
}

TEST(ParallelClustering, CleaningMatchesTheBreadthFirstReference) {
  // Random labels: clusters in many pieces. The chunk-wise union-find keeps the piece the BFS
  // reference keeps (the heaviest, the first on a tie), for any thread count, chunk size and
  // storage.
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, kTbbThreads);
  const MeshBuffers elephant = read_mesh(test::data_path("cgal_elephant.off"));
  WorkSpace files("", 0);  // every array in a mapped work file
  for (uint64_t faces_per_chunk : {uint64_t(1) << 20, uint64_t(300)}) {
    MeshStore store = MeshStore::build(elephant.view(), {.faces_per_chunk = faces_per_chunk});
    const MeshView view = store.view();
    const ItemData items = compute_item_data(view);
    std::mt19937 rng(7);
    for (uint32_t K : {3u, 40u, 400u}) {
      std::vector<int32_t> random(view.vertex_count());
      for (int32_t& l : random) l = int32_t(rng() % K);
      uint32_t disconnected = 0;
      const std::vector<int32_t> expected = reference_cleaning(view, items, random, K, disconnected);
      ASSERT_GT(disconnected, 0u);
      EXPECT_TRUE(clusters_connected(view, expected, K));
      EXPECT_FALSE(clusters_connected(view, random, K));
      for (uint32_t threads : {1u, 2u, 8u}) {
        tbb::global_control t(tbb::global_control::max_allowed_parallelism, threads);
        for (ArrayStorage* storage : {&ram_storage(), static_cast<ArrayStorage*>(&files)}) {
          std::vector<int32_t> labels = random;
          ClusteringReport report;
          clean_clusters(view, items, labels, K, report, *storage);
          EXPECT_EQ(report.disconnected_clusters, disconnected);
          EXPECT_TRUE(labels == expected) << K << " T=" << threads << " chunk " << faces_per_chunk;
        }
      }
    }
  }
}

TEST(ParallelClustering, OneThreadIsReproducibleWhateverTheStorage) {
  // One code path: a single thread runs the region visits in order. Its output is the same on
  // every run, and whether the arrays sized by V live in RAM or in mapped work files.
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, kTbbThreads);
  const MeshBuffers torus = make_torus(60, 24);
  MeshStore store = MeshStore::build(torus.view(), {.faces_per_chunk = 500});
  RemeshOptions a = options_for(150, Metric::I, 1, false, 64);  // many regions and visits
  WorkSpace files("", 0);  // every array sized by V in a mapped work file
  const RemeshResult ra = remesh(store.view(), a), rb = remesh(store.view(), a), rf = remesh(store.view(), a, files);
  EXPECT_GT(files.peak_file_bytes(), 0u);
  for (const RemeshResult* r : {&rb, &rf}) {
    EXPECT_TRUE(test::to_vector(ra.cluster_of_vertex) == test::to_vector(r->cluster_of_vertex));
    EXPECT_TRUE(ra.mesh.positions == r->mesh.positions);
    EXPECT_EQ(ra.clustering.final_energy, r->clustering.final_energy);
  }
  EXPECT_GT(ra.clustering.moves_per_loop.size(), 1u);
}

TEST(ParallelClustering, StressManySmallRandomRuns) {
  // Hundreds of small runs: random thread counts (1-8, oversubscribed), seeds, metrics, region
  // sizes and modes. Every output must keep the remeshing guarantees.
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, kTbbThreads);
  struct Shape {
    std::string name;
    MeshBuffers mesh;
    uint32_t min_n, max_n;
  };
  std::vector<Shape> shapes;
  shapes.push_back({"sphere", make_icosphere(3), 60, 200});
  shapes.push_back({"torus", make_torus(40, 16), 120, 250});
  // The elephant's trunk and legs are thinner than a cluster below N≈900 (remesh_test.cpp: the
  // topology may change there, reported); above it every run must keep genus 3.
  shapes.push_back({"elephant", read_mesh(test::data_path("cgal_elephant.off")), 900, 1300});
  std::vector<MeshStore> stores;
  std::vector<TopologyStats> inputs;
  for (const Shape& s : shapes) {
    stores.push_back(MeshStore::build(s.mesh.view()));
    inputs.push_back(compute_topology_stats(s.mesh.view()));
  }
  const Metric metrics[] = {Metric::I, Metric::IQ, Metric::A, Metric::AQ};
  std::mt19937_64 rng(20240605);
  const int runs = kThreadSanitizer ? 120 : 300;
  int topology_changes = 0, aq_elephant_runs = 0, aq_elephant_changes = 0;
  for (int i = 0; i < runs; ++i) {
    const size_t s = rng() % shapes.size();
    const uint32_t n = shapes[s].min_n + uint32_t(rng() % (shapes[s].max_n - shapes[s].min_n + 1));
    const Metric metric = metrics[rng() % 4];
    const uint32_t threads = 1 + uint32_t(rng() % 8);
    const bool deterministic = rng() % 4 == 0;
    const uint32_t region_vertices = 32u << (rng() % 5);  // 32 … 512
    RemeshOptions o = options_for(n, metric, threads, deterministic, region_vertices);
    o.seed = rng();
    const std::string what = shapes[s].name + " N=" + std::to_string(n) + " " + metric_name(metric) + " T=" +
                             std::to_string(threads) + (deterministic ? " det" : "") + " regions of " +
                             std::to_string(region_vertices) + " seed " + std::to_string(o.seed);
    RemeshResult r;
    try {
      r = remesh(stores[s].view(), o);
    } catch (const std::exception& e) {
      ADD_FAILURE() << what << ": " << e.what();
      continue;
    }
    EXPECT_EQ(r.clusters, n) << what;
    expect_valid_closed_output(r, inputs[s], what);
    // AQ on the elephant changes its topology in ~2 % of runs at these N, serial or parallel,
    // with the global initial sampling as with the chunk-wise one (measured over ~1100 seeds
    // each): reported, it is counted and bounded below; any other change is a failure.
    const bool aq_elephant = shapes[s].name == "elephant" && metric == Metric::AQ;
    aq_elephant_runs += aq_elephant;
    if (r.checks.topology_changed) {
      // Report whether the serial clustering from the same seed keeps the topology here.
      RemeshOptions serial = o;
      serial.clustering.loops.threads = 1;
      serial.clustering.loops.deterministic = false;
      const RemeshResult rs = remesh(stores[s].view(), serial);
      const std::string message = what + ": topology changed (serial from the same seed: " +
                                  (rs.checks.topology_changed ? "changed too" : "kept") + ")";
      if (aq_elephant) std::printf("[ stress   ] %s\n", message.c_str());
      else ADD_FAILURE() << message;
      ++topology_changes;
      aq_elephant_changes += aq_elephant;
    }
    if (::testing::Test::HasFailure()) break;  // one failing configuration is enough to report
  }
  std::printf("[ stress   ] %d runs, %d reported topology changes\n", runs, topology_changes);
  EXPECT_LE(aq_elephant_changes, std::max(2, aq_elephant_runs / 10)) << "of " << aq_elephant_runs << " AQ elephant runs";
}

}  // namespace
}  // namespace streamcvd
