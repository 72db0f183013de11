#pragma once
// DQO_HD marks maths shared by the CPU reference and the CUDA kernels: `__host__ __device__` under
// nvcc, nothing otherwise, so the same header is compiled and unit-tested on the host.
#if defined(__CUDACC__)
#define DQO_HD __host__ __device__ __forceinline__
#else
#define DQO_HD inline
#endif
