// Internal to the store (not installed): the layout of a store directory — file names, the
// arrays and their sizes from the header — and MeshStore's state, shared by the build
// (store.cpp) and the opening and validation (store_open.cpp).
#pragma once

#include <sys/mman.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/default_init_vector.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd {

namespace store_detail {

inline constexpr uint32_t kStoreVersion = 2;
inline constexpr const char* kHeaderFile = "header.bin";
inline constexpr const char* kAttributesFile = "attributes.txt";
inline constexpr const char* kCleaningFile = "cleaning.txt";  // a cleaned store's record (store_clean.h)

// One array file of the store: its name, element size and entry count from the header.
struct ArrayFile {
  const char* name;
  size_t element;
  uint64_t count;
};

enum ArrayIndex { kPositions, kTriangles, kVvOffsets, kVv, kVfOffsets, kVf, kFlags, kChunks, kNeighbours, kOriginal,
                  kAttributes, kArrayCount };

inline std::vector<ArrayFile> array_files(const StoreHeader& h) {
  return {{"positions.f32", 4, 3 * h.vertex_count},
          {"triangles.u32", 4, 3 * h.face_count},
          {"vv_offsets.u64", 8, h.vertex_count + 1},
          {"vv.u32", 4, h.vertex_vertex_count},
          {"vf_offsets.u64", 8, h.vertex_count + 1},
          {"vf.u32", 4, h.vertex_face_count},
          {"flags.u8", 1, h.vertex_count},
          {"chunks.bin", sizeof(Chunk), h.chunk_count},
          {"chunk_neighbours.u32", 4, h.chunk_neighbour_count},
          {"original_ids.u32", 4, h.vertex_count},
          {"vertex_attributes.f32", 4, uint64_t(h.attribute_count) * h.vertex_count}};
}

// A mapped file's bytes as an array of T (the size was checked against the header).
template <typename T>
std::span<const T> array_of(std::span<const std::byte> bytes) {
  return {reinterpret_cast<const T*>(bytes.data()), bytes.size() / sizeof(T)};
}

}  // namespace store_detail

struct MeshStore::Impl {
  StoreHeader header;
  std::string directory;                        // of an opened store ("" in RAM)
  std::vector<DefaultInitVector<std::byte>> ram;  // arrays of a store built in RAM (by ArrayIndex)
  struct Mapping {
    void* address = nullptr;
    size_t length = 0;
  };
  std::vector<Mapping> mappings;                // files of an opened store (by ArrayIndex)
  std::vector<std::span<const std::byte>> bytes;  // every array, in RAM or mapped
  std::vector<VertexAttribute> attributes;
  std::string cleaning;                         // cleaning_record() of a cleaned store, else ""
  MeshView view;
  std::span<const uint32_t> original_view;
  std::span<const float> attribute_view;
  std::unique_ptr<std::atomic<uint8_t>[]> validated;  // per chunk

  Impl() = default;
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  ~Impl() {
    for (const Mapping& m : mappings)
      if (m.address) ::munmap(m.address, m.length);
  }

  void make_views() {
    MeshView& m = view;
    m.positions = store_detail::array_of<float>(bytes[store_detail::kPositions]);
    m.triangles = store_detail::array_of<uint32_t>(bytes[store_detail::kTriangles]);
    m.vertex_vertex_offsets = store_detail::array_of<uint64_t>(bytes[store_detail::kVvOffsets]);
    m.vertex_vertex = store_detail::array_of<uint32_t>(bytes[store_detail::kVv]);
    m.vertex_face_offsets = store_detail::array_of<uint64_t>(bytes[store_detail::kVfOffsets]);
    m.vertex_face = store_detail::array_of<uint32_t>(bytes[store_detail::kVf]);
    m.vertex_flags = store_detail::array_of<uint8_t>(bytes[store_detail::kFlags]);
    m.chunks = store_detail::array_of<Chunk>(bytes[store_detail::kChunks]);
    m.chunk_neighbours = store_detail::array_of<uint32_t>(bytes[store_detail::kNeighbours]);
    original_view = store_detail::array_of<uint32_t>(bytes[store_detail::kOriginal]);
    attribute_view = store_detail::array_of<float>(bytes[store_detail::kAttributes]);
    validated = std::make_unique<std::atomic<uint8_t>[]>(header.chunk_count);
  }
};

}  // namespace streamcvd
