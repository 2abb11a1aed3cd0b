#pragma once

#include <cstdlib>  // defines __GLIBC__ where the C library is glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace penumbra {

// Hands the heap's freed pages back to the system. glibc keeps what small blocks free in its heaps and
// returns it only from the top; a large array copied out of many small ones (the links of a refinement
// pass) was then resident twice. Elsewhere a no-op: the peak is higher, the answer the same.
inline void releaseFreedMemory() {
#if defined(__GLIBC__)
    malloc_trim(0);
#endif
}

}  // namespace penumbra
