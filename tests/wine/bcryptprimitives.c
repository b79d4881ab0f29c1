/* Test-only stand-in for Windows' bcryptprimitives.dll, which Debian's wine 8 lacks: Rust's std (1.78 on) asks
 * ProcessPrng for random bytes. Built next to the test master, never shipped in an FMU; fills the buffer from
 * RtlGenRandom (advapi32's SystemFunction036), which wine has. */
#include <windows.h>

BOOLEAN WINAPI SystemFunction036(PVOID buffer, ULONG length);

__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length) {
    while (length > 0) {
        ULONG chunk = length > 0x40000000 ? 0x40000000 : (ULONG)length;
        if (!SystemFunction036(data, chunk))
            return FALSE;
        data += chunk;
        length -= chunk;
    }
    return TRUE;
}
