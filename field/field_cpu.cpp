// CPU build of the field builders: the shared implementation on the OpenMP backend.
#include "core/launch_cpu.h"
#include "field.h"
#include "builders.h"

#include <type_traits>

#define SPHRAY_BK cpu_backend
namespace sphray::cpu_backend {
#include "nsearch/sort.inl"
#include "field_impl.inl"
}  // namespace sphray::cpu_backend

namespace sphray {

std::unique_ptr<FieldBuilder> make_cpu_field_builder(const FieldSetup& s, FieldKind kind) {
  return std::make_unique<cpu_backend::FieldBuilderImpl>(s, kind);
}

}  // namespace sphray
