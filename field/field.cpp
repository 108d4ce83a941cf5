#include "field.h"

namespace sphray {

std::unique_ptr<FieldBuilder> make_field_builder(Backend b, const FieldSetup& s, FieldKind kind) {
  return b == Backend::Cuda ? make_cuda_field_builder(s, kind) : make_cpu_field_builder(s, kind);
}

#if !defined(SPHRAY_HAVE_CUDA)
std::unique_ptr<FieldBuilder> make_cuda_field_builder(const FieldSetup&, FieldKind) { throw_no_cuda(); }
#endif

}  // namespace sphray
