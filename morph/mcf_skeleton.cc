#include "morph/mcf_skeleton.h"

#include <sys/mman.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <new>
#include <vector>

// CGAL's skeletonization keeps the edges it will collapse in a std::set ordered by the
// addresses of its Polyhedron_3's halfedges, so with the ordinary heap the skeleton depends on
// what the program allocated before (one mesh gave 263 to 283 nodes in different programs).
// Every CGAL container of this translation unit therefore allocates from an arena whose
// addresses are a function of the calls made on it alone: one reserved address range, handed
// out in increasing order, freed blocks reused last-in first-out per size.
namespace vb::morph::mcf_internal {

class Arena {
 public:
  Arena() {
    void* base = mmap(nullptr, kReserve, PROT_READ | PROT_WRITE,
                      MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (base == MAP_FAILED) throw std::bad_alloc();
    base_ = static_cast<std::byte*>(base);
  }
  ~Arena() { munmap(base_, kReserve); }
  Arena(const Arena&) = delete;
  Arena& operator=(const Arena&) = delete;

  void* Allocate(std::size_t bytes) {
    const std::size_t size = Round(bytes);
    if (size / kGrain < free_.size() && !free_[size / kGrain].empty()) {
      void* p = free_[size / kGrain].back();
      free_[size / kGrain].pop_back();
      return p;
    }
    if (size > kReserve - used_) throw std::bad_alloc();
    void* p = base_ + used_;
    used_ += size;
    return p;
  }
  void Deallocate(void* p, std::size_t bytes) {
    const std::size_t size = Round(bytes);
    if (size / kGrain >= free_.size()) free_.resize(size / kGrain + 1);
    free_[size / kGrain].push_back(p);
  }
  bool Owns(const void* p) const {
    const auto* b = static_cast<const std::byte*>(p);
    return b >= base_ && b < base_ + kReserve;
  }

  /// The arena allocations go to on this thread, or null (the ordinary heap).
  static Arena*& Current() {
    thread_local Arena* current = nullptr;
    return current;
  }

 private:
  static constexpr std::size_t kGrain = alignof(std::max_align_t);
  // Address space only: pages are taken as they are touched.
  static constexpr std::size_t kReserve = std::size_t{16} << 30;
  static std::size_t Round(std::size_t bytes) {
    return (std::max<std::size_t>(bytes, 1) + kGrain - 1) / kGrain * kGrain;
  }
  std::byte* base_ = nullptr;
  std::size_t used_ = 0;
  std::vector<std::vector<void*>> free_;  // by size / kGrain
};

template <class T>
struct ArenaAllocator {
  using value_type = T;
  ArenaAllocator() = default;
  template <class U>
  ArenaAllocator(const ArenaAllocator<U>&) {}  // NOLINT: rebinding is implicit
  T* allocate(std::size_t n) {
    Arena* arena = Arena::Current();
    return static_cast<T*>(arena ? arena->Allocate(n * sizeof(T)) : ::operator new(n * sizeof(T)));
  }
  void deallocate(T* p, std::size_t n) {
    Arena* arena = Arena::Current();
    if (arena && arena->Owns(p)) {
      arena->Deallocate(p, n * sizeof(T));
    } else {
      ::operator delete(p);
    }
  }
  template <class U>
  bool operator==(const ArenaAllocator<U>&) const {
    return true;
  }
};

}  // namespace vb::morph::mcf_internal

#define CGAL_ALLOCATOR(T) vb::morph::mcf_internal::ArenaAllocator<T>

#include <CGAL/Mean_curvature_flow_skeletonization.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/extract_mean_curvature_flow_skeleton.h>

#include "io/error.h"

namespace vb::morph {

SkeletonGraph MeanCurvatureFlowSkeleton(const geometry::TriangleMesh& mesh) {
  // Made before, and so destroyed after, every CGAL object below.
  mcf_internal::Arena arena;
  struct Use {
    explicit Use(mcf_internal::Arena* a) { mcf_internal::Arena::Current() = a; }
    ~Use() { mcf_internal::Arena::Current() = nullptr; }
    Use(const Use&) = delete;
    Use& operator=(const Use&) = delete;
  } use(&arena);
  using Kernel = CGAL::Simple_cartesian<double>;
  using Point = Kernel::Point_3;
  using SurfaceMesh = CGAL::Surface_mesh<Point>;
  using Skeletonization = CGAL::Mean_curvature_flow_skeletonization<SurfaceMesh>;

  SurfaceMesh sm;
  std::vector<SurfaceMesh::Vertex_index> handles;
  handles.reserve(static_cast<std::size_t>(mesh.num_vertices()));
  for (int i = 0; i < mesh.num_vertices(); ++i)
    handles.push_back(sm.add_vertex(Point(mesh.V(0, i), mesh.V(1, i), mesh.V(2, i))));
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const auto face = sm.add_face(handles[static_cast<std::size_t>(mesh.F(0, f))],
                                  handles[static_cast<std::size_t>(mesh.F(1, f))],
                                  handles[static_cast<std::size_t>(mesh.F(2, f))]);
    if (face == SurfaceMesh::null_face()) {
      throw InputError("skeleton: face " + std::to_string(f) + " makes the template non-manifold");
    }
  }
  if (!CGAL::is_closed(sm)) throw InputError("skeleton: the template mesh is not closed");

  Skeletonization::Skeleton skeleton;
  CGAL::extract_mean_curvature_flow_skeleton(sm, skeleton);

  SkeletonGraph out;
  const auto n = boost::num_vertices(skeleton);
  out.nodes.resize(3, static_cast<Eigen::Index>(n));
  out.support.resize(n);
  for (const auto v : CGAL::make_range(boost::vertices(skeleton))) {
    const Point& p = skeleton[v].point;
    out.nodes.col(static_cast<Eigen::Index>(v)) = Eigen::Vector3d(p.x(), p.y(), p.z());
    for (const auto mv : skeleton[v].vertices) out.support[v].push_back(static_cast<int>(mv.idx()));
  }
  for (const auto e : CGAL::make_range(boost::edges(skeleton))) {
    out.edges.push_back({static_cast<int>(boost::source(e, skeleton)),
                         static_cast<int>(boost::target(e, skeleton))});
  }
  return out;
}

}  // namespace vb::morph
