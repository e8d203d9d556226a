#include "daemon/memory_budget.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <memory>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include "daemon/job.h"
#include "daemon/saw_link.h"
#include "daemon/saw_session.h"
#include "io/lcm_publisher.h"
#include "morph/morph_carcass.h"
#include "morph/morpher.h"
#include "perception/carcass_generator.h"
#include "tests/support/lamb_fixture.h"

namespace vb::daemon {
namespace {

constexpr std::size_t kArenaBytes = std::size_t{256} << 20;

// The arena is reserved once per process, as the daemon does at start.
class MemoryBudgetTest : public test::LambTemplateTest {
 protected:
  static void SetUpTestSuite() {
    test::LambTemplateTest::SetUpTestSuite();
    if (MemoryBudgetAvailable()) {
      const std::string why = ReserveMemoryBudget(kArenaBytes);
      ASSERT_EQ(why, "");
    }
  }
  void SetUp() override {
    if (!MemoryBudgetAvailable()) GTEST_SKIP() << "sanitizer build: no memory budget";
  }
};

// Runs @p work on a new thread that has a budget, as the daemon's loop threads do.
template <typename Work>
void OnBudgetThread(Work&& work) {
  std::thread([&] {
    const MemoryBudgetScope scope;
    work();
  }).join();
}

TEST_F(MemoryBudgetTest, ReservesOnlyOnce) {
  EXPECT_EQ(GetMemoryBudgetStats().arena_bytes, kArenaBytes);
  EXPECT_EQ(ReserveMemoryBudget(kArenaBytes), "the memory budget's arena is already reserved");
}

// Every way C and C++ code asks for memory lands in the arena on a budget thread, and
// nowhere near it on another thread.
TEST_F(MemoryBudgetTest, EveryAllocationOfABudgetThreadLandsInTheArena) {
  const MemoryBudgetStats before = GetMemoryBudgetStats();
  OnBudgetThread([] {
    void* m = std::malloc(100);
    void* c = std::calloc(1000, 8);
    void* r = std::realloc(std::malloc(16), 1 << 20);  // moved on growth
    void* a = std::aligned_alloc(4096, 8192);
    void* pm = nullptr;
    ASSERT_EQ(posix_memalign(&pm, 256, 3000), 0);
    auto* n = new double[1000];
    auto* big = new std::array<char, 20 << 20>;  // beyond mimalloc's large-object size
    struct alignas(64) Aligned {
      double x[8];
    };
    auto* al = new Aligned;
    std::vector<int> v;
    for (int i = 0; i < 100000; ++i) v.push_back(i);
    std::string s(1000, 'x');
    Eigen::MatrixXd e = Eigen::MatrixXd::Random(300, 300);
    Eigen::MatrixXd product = e * e.transpose();
    const std::vector<const void*> blocks = {
        m, c, r, a, pm, n, big, al, v.data(), s.data(), product.data()};
    for (std::size_t i = 0; i < blocks.size(); ++i)
      EXPECT_TRUE(InMemoryBudget(blocks[i])) << "block " << i;
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(a) % 4096, 0u);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(pm) % 256, 0u);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(al) % 64, 0u);
    for (void* p : {m, c, r, a, pm}) std::free(p);
    delete[] n;
    delete big;
    delete al;
  });
  const MemoryBudgetStats after = GetMemoryBudgetStats();
  EXPECT_GE(after.arena_allocations - before.arena_allocations, 12);
  EXPECT_EQ(after.heap_allocations, before.heap_allocations);

  // A thread without a budget allocates elsewhere, and is counted as such.
  std::thread([] {
    const auto block = std::make_unique<char[]>(100);
    EXPECT_FALSE(InMemoryBudget(block.get()));
  }).join();
  EXPECT_GT(GetMemoryBudgetStats().other_allocations, after.other_allocations);
}

// A block made on a budget thread and freed on another gives its bytes back.
TEST_F(MemoryBudgetTest, BlocksFreedOnAnotherThreadLeaveTheArena) {
  const std::size_t live_before = GetMemoryBudgetStats().arena_live_bytes;
  std::vector<std::unique_ptr<double[]>> blocks;
  blocks.reserve(100);  // this thread's
  OnBudgetThread([&] {
    for (int i = 0; i < 100; ++i) blocks.emplace_back(new double[10000]);
  });
  EXPECT_GE(GetMemoryBudgetStats().arena_live_bytes, live_before + 100 * 80000);
  blocks.clear();
  EXPECT_EQ(GetMemoryBudgetStats().arena_live_bytes, live_before);
  // The peak counts the frees of threads without a budget too: it does not creep up.
  ResetMemoryBudgetPeak();
  const MemoryBudgetStats after = GetMemoryBudgetStats();
  EXPECT_EQ(after.arena_peak_bytes, after.arena_live_bytes);
}

// Past the budget, allocations still succeed, from the ordinary heap, and are counted: the
// daemon's log then says the budget is too small. Once memory is freed, the arena serves
// again.
TEST_F(MemoryBudgetTest, AFullArenaFallsBackToTheHeapAndCountsIt) {
  const MemoryBudgetStats before = GetMemoryBudgetStats();
  OnBudgetThread([] {
    std::vector<void*> blocks;
    int outside = 0;
    for (std::size_t total = 0; total < kArenaBytes * 3 / 2; total += 40 << 20) {
      void* p = std::malloc(40 << 20);
      ASSERT_NE(p, nullptr);
      outside += !InMemoryBudget(p);
      blocks.push_back(p);
    }
    EXPECT_GE(outside, 3);
    EXPECT_LT(outside, static_cast<int>(blocks.size()));
    for (void* p : blocks) std::free(p);
    void* again = std::malloc(40 << 20);
    EXPECT_TRUE(InMemoryBudget(again));
    std::free(again);
  });
  EXPECT_GE(GetMemoryBudgetStats().heap_allocations - before.heap_allocations, 3);
}

// The proof for the part of the daemon that allocates: the job thread's whole job
// (morph, cut-lines message, saw job, CAN frames, LCM publish), for
// several carcasses in a row. After the first, no allocation reaches the heap, and the
// arena holds no more after each job than after the first: nothing accumulates.
TEST_F(MemoryBudgetTest, SteadyStateJobsAllocateOnlyFromTheArenaAndGiveItAllBack) {
  io::LcmPublisher publisher("memq://");
  std::unique_ptr<SawLink> saw = MakeSawLink("loopback");
  SawSession session(saw.get(), {});
  morph::MorphOptions options;
  options.coarse.upright.enabled = true;
  std::vector<Eigen::Matrix3Xd> clouds;
  for (std::uint64_t seed : {31u, 32u, 33u, 34u})
    clouds.push_back(test::HangingCloud(*carcass_, seed, 0.003));
  struct After {
    MemoryBudgetStats stats;
    std::string status;
  };
  std::vector<After> after;
  after.reserve(clouds.size());  // here, so that the record itself does not grow in the arena
  // As the daemon makes it: once, its worker inside the budget.
  morph::Morpher morpher(*model_, carcass_->annotations, options,
                         {.threads = 2, .worker_wrapper = [](const std::function<void()>& body) {
                            const MemoryBudgetScope budget;
                            body();
                          }});
  OnBudgetThread([&] {
    std::uint32_t number = 0;
    for (const Eigen::Matrix3Xd& cloud : clouds) {
      ++number;
      ResetMemoryBudgetPeak();
      {
        const morph::CarcassResult result = morpher.Morph(cloud, {});
        char id[16];
        std::snprintf(id, sizeof(id), "C%06u", number);
        vbutcher::cut_lines_t message =
            MakeCutLines(result, carcass_->annotations, {id, number, "lamb", 1, 0});
        io::saw::Job job;
        std::string why = MakeSawJob(result, Eigen::Isometry3d::Identity(), 0.6, number,
                                     static_cast<std::uint8_t>(number), &job);
        Verdict verdict = Verdict::kRefused;
        if (why.empty()) {
          // The morph outlasted the saw's heartbeat timeout: the first heartbeat finds it in
          // safe stop, three more take it out.
          for (std::uint32_t k = 0; k < 4; ++k)
            session.SendHeartbeat(io::saw::DaemonState::kReady, 100 * (4 * number + k));
          const JobOutcome outcome = session.SendJob(job);
          verdict = outcome.verdict;
          why = outcome.reason;
        }
        message.saw_verdict = static_cast<std::int8_t>(verdict);
        message.status = why.empty() ? ToString(verdict) : why;
        publisher.Publish(message);
        after.push_back({GetMemoryBudgetStats(), message.status});
      }
      after.back().stats = GetMemoryBudgetStats();  // with the job's memory freed
    }
  });
  ASSERT_EQ(after.size(), clouds.size());
  for (std::size_t j = 0; j < after.size(); ++j) EXPECT_EQ(after[j].status, "accepted") << "job " << j;
  const MemoryBudgetStats& first = after.front().stats;
  long fewest = std::numeric_limits<long>::max(), most = 0;
  for (std::size_t j = 1; j < after.size(); ++j) {
    const MemoryBudgetStats& s = after[j].stats;
    const MemoryBudgetStats& previous = after[j - 1].stats;
    EXPECT_EQ(s.heap_allocations, first.heap_allocations) << "job " << j;
    // A whole job (morph, cuts, message, CAN) makes 4,400 to 4,800 allocations here, the
    // morph alone about 4,000; a job whose morph ran on another thread, a few hundred.
    const auto job = static_cast<long>(s.arena_allocations - previous.arena_allocations);
    fewest = std::min(fewest, job);
    most = std::max(most, job);
    EXPECT_GT(job, 2000) << "job " << j << " hardly allocated: is it still running on this thread?";
    EXPECT_LE(s.arena_live_bytes, first.arena_live_bytes) << "job " << j;
    // Nothing outside the arena either: the morph's worker is inside the budget, and each
    // solve runs on the thread that asks for it (docs/decisions.md).
    EXPECT_EQ(s.other_allocations - previous.other_allocations, 0) << "job " << j;
    EXPECT_LT(s.arena_peak_bytes, kArenaBytes / 2) << "job " << j;  // the daemon's is 512 MiB
  }
  if (after.size() > 1) {
    RecordProperty("job_allocations_fewest", static_cast<int>(fewest));
    RecordProperty("job_allocations_most", static_cast<int>(most));
  }
}

}  // namespace
}  // namespace vb::daemon
