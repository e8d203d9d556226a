#pragma once

// Include before any CGAL header, in every translation unit that includes CGAL: it makes
// CGAL_ALLOCATOR, the allocator of CGAL's own containers (Polyhedron_3's halfedge lists,
// Compact_container, Handle_for), the same type everywhere in the program.
//
// Some CGAL algorithms order their work by the addresses of the elements of those containers
// (the mean curvature flow skeleton collapses edges in the order of a std::set of halfedge
// handles), so with the ordinary heap their result depends on what the process allocated
// before. While a CgalArenaScope is alive on a thread, that thread's CGAL containers allocate
// from an arena whose addresses increase in the order of the calls, freed blocks reused last
// in first out per size: the relative order of addresses, and so such a result, then follows
// from the calls alone. Elsewhere the allocator is the ordinary heap.
#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <new>
#include <stdexcept>
#include <string>

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/asan_interface.h>
#define VB_ARENA_POISON(p, n) ASAN_POISON_MEMORY_REGION(p, n)
#define VB_ARENA_UNPOISON(p, n) ASAN_UNPOISON_MEMORY_REGION(p, n)
#else
#define VB_ARENA_POISON(p, n) ((void)(p), (void)(n))
#define VB_ARENA_UNPOISON(p, n) ((void)(p), (void)(n))
#endif

namespace vb::geometry {

/// One reserved address range handed out in increasing order. Address space is reserved
/// without access (not charged against the commit limit) and opened in steps as it is used.
class CgalArena {
 public:
  /// @throws std::runtime_error naming the size and the system's reason when no range of at
  ///   least 256 MiB can be reserved.
  CgalArena() {
    for (std::size_t size = kMaxReserve; size >= kMinReserve; size /= 2) {
      void* base =
          mmap(nullptr, size, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
      if (base != MAP_FAILED) {
        base_ = static_cast<std::byte*>(base);
        reserved_ = size;
        return;
      }
    }
    throw std::runtime_error("CGAL arena: cannot reserve " + std::to_string(kMinReserve >> 20) +
                             " MiB of address space: " + std::strerror(errno));
  }
  ~CgalArena() { munmap(base_, reserved_); }
  CgalArena(const CgalArena&) = delete;
  CgalArena& operator=(const CgalArena&) = delete;

  /// @throws std::bad_alloc when the range is used up.
  void* Allocate(std::size_t bytes) {
    const std::size_t size = Round(bytes);
    if (size / kGrain < free_.size() && free_[size / kGrain] != nullptr) {
      FreeBlock* block = free_[size / kGrain];
      VB_ARENA_UNPOISON(block, size);
      free_[size / kGrain] = block->next;
      return block;
    }
    if (size > reserved_ - used_) throw std::bad_alloc();
    if (used_ + size > open_) {
      const std::size_t want = std::min(reserved_, (used_ + size + kStep - 1) / kStep * kStep);
      if (mprotect(base_ + open_, want - open_, PROT_READ | PROT_WRITE) != 0)
        throw std::bad_alloc();
      open_ = want;
    }
    void* p = base_ + used_;
    used_ += size;
    return p;
  }
  /// Never allocates. Blocks larger than the free lists hold are not reused.
  void Deallocate(void* p, std::size_t bytes) noexcept {
    const std::size_t size = Round(bytes);
    if (size / kGrain < free_.size()) {
      auto* block = static_cast<FreeBlock*>(p);
      block->next = free_[size / kGrain];
      free_[size / kGrain] = block;
    }
    VB_ARENA_POISON(p, size);
  }
  bool Owns(const void* p) const {
    const auto a = reinterpret_cast<std::uintptr_t>(p);
    const auto b = reinterpret_cast<std::uintptr_t>(base_);
    return a >= b && a - b < reserved_;
  }
  std::size_t used_bytes() const { return used_; }

  /// The arena this thread's CGAL containers allocate from, or null (the ordinary heap).
  static CgalArena*& Current() {
    thread_local CgalArena* current = nullptr;
    return current;
  }

 private:
  struct FreeBlock {
    FreeBlock* next;
  };
  static constexpr std::size_t kGrain = alignof(std::max_align_t);
  static constexpr std::size_t kMaxReserve = std::size_t{16} << 30;
  static constexpr std::size_t kMinReserve = std::size_t{256} << 20;
  static constexpr std::size_t kStep = std::size_t{64} << 20;
  static std::size_t Round(std::size_t bytes) {
    return (std::max<std::size_t>(bytes, sizeof(FreeBlock)) + kGrain - 1) / kGrain * kGrain;
  }
  std::byte* base_ = nullptr;
  std::size_t reserved_ = 0;
  std::size_t used_ = 0;
  std::size_t open_ = 0;
  std::array<FreeBlock*, 4096 / kGrain + 1> free_{};  // by size / kGrain, up to 4 KiB
};

/// Makes @p arena the current thread's CGAL arena for its lifetime; restores the previous.
/// The arena must outlive every CGAL object made while the scope is alive.
class CgalArenaScope {
 public:
  explicit CgalArenaScope(CgalArena* arena) : previous_(CgalArena::Current()) {
    CgalArena::Current() = arena;
  }
  ~CgalArenaScope() { CgalArena::Current() = previous_; }
  CgalArenaScope(const CgalArenaScope&) = delete;
  CgalArenaScope& operator=(const CgalArenaScope&) = delete;

 private:
  CgalArena* previous_;
};

/// The allocator CGAL_ALLOCATOR names: the current thread's CgalArena, else the heap.
template <class T>
struct CgalAllocator {
  using value_type = T;
  CgalAllocator() = default;
  template <class U>
  CgalAllocator(const CgalAllocator<U>&) {}  // NOLINT(google-explicit-constructor): rebinding
  T* allocate(std::size_t n) {
    static_assert(alignof(T) <= alignof(std::max_align_t), "the arena aligns to max_align_t");
    if (n > std::numeric_limits<std::size_t>::max() / sizeof(T)) throw std::bad_alloc();
    CgalArena* arena = CgalArena::Current();
    return static_cast<T*>(arena ? arena->Allocate(n * sizeof(T)) : ::operator new(n * sizeof(T)));
  }
  void deallocate(T* p, std::size_t n) noexcept {
    CgalArena* arena = CgalArena::Current();
    if (arena && arena->Owns(p)) {
      arena->Deallocate(p, n * sizeof(T));
    } else {
      ::operator delete(p);
    }
  }
  template <class U>
  bool operator==(const CgalAllocator<U>&) const {
    return true;
  }
};

}  // namespace vb::geometry

#ifdef CGAL_ALLOCATOR
#error "geometry/cgal_arena.h must be included before any CGAL header"
#endif
#define CGAL_ALLOCATOR(T) vb::geometry::CgalAllocator<T>
