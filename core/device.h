// Which backend runs the per-element code, and what the host can ask about
// the CUDA device. Both backends build from one source (docs/design.md); a
// build without nvcc answers that no device is present.
#pragma once

#include <cstddef>
#include <string>

namespace sphray {

enum class Backend { Cpu, Cuda };
const char* backend_name(Backend b);

bool cuda_available();           // built with CUDA and a device is present
std::string cuda_device_name();  // empty when none
size_t cuda_free_memory();       // bytes, 0 when none
int cuda_device_count();         // 0 when none
// Makes device k current for this process (one GPU per rank of a decomposed run).
void use_cuda_device(int k);

// What a stage says when the CUDA backend is asked for in a build without it.
[[noreturn]] void throw_no_cuda();

}  // namespace sphray
