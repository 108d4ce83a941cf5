// CUDA build of the field builders: the shared implementation on the CUDA backend.
#include "core/launch_cuda.cuh"
#include "field.h"
#include "builders.h"

#include <type_traits>

#define SPHRAY_BK cuda_backend
namespace sphray::cuda_backend {
#include "nsearch/sort.inl"
#include "field_impl.inl"
}  // namespace sphray::cuda_backend

namespace sphray {

std::unique_ptr<FieldBuilder> make_cuda_field_builder(const FieldSetup& s, FieldKind kind) {
  if (!cuda_available()) throw std::runtime_error("the CUDA backend was asked for, but no CUDA device is present");
  return std::make_unique<cuda_backend::FieldBuilderImpl>(s, kind);
}

}  // namespace sphray
