/*
 * state_handles.h - the handles an FMU gives a host for its FMU states, shared by the native
 * plumbing (cosimulation.c) and the Python FMUs' loader shim (fmu_src/loader/fmi2_shim.c, which
 * includes it from here).  Header-only.
 *
 * A handle is not the address of the state's record but a number the library issues once: a
 * serial number (1, 2, ...), a tag of this loaded copy of the library in the high bits (bits of
 * the page of one of its variables, `anchor`), and on 64-bit platforms bit 62 set and bit 63
 * clear, which makes it no address a process can have on x86-64.  A freed state's handle
 * therefore never comes back as a live state when the memory is reused, a handle of another
 * loaded copy is told from one of this copy, and a handle this copy issued and freed since is
 * told from one it never issued.  The caller keeps the live records (a handle is looked up, never
 * read) and the last serial number, under its own lock.
 */
#ifndef DRIFTFMU_STATE_HANDLES_H
#define DRIFTFMU_STATE_HANDLES_H

#include <stdint.h>

#if UINTPTR_MAX > 0xFFFFFFFFu
#define STATE_SERIAL_BITS 36
#define STATE_TAG_MASK 0x3FFFFFFu
#define STATE_MARK ((uint64_t)1 << 62)
#else
#define STATE_SERIAL_BITS 24
#define STATE_TAG_MASK 0xFFu
#define STATE_MARK 0u
#endif
#define STATE_SERIAL_MASK (((uint64_t)1 << STATE_SERIAL_BITS) - 1)

/* The serial number after `last` (1 after the last one there is room for). */
static inline uint64_t state_next_serial(uint64_t last)
{
    return last < STATE_SERIAL_MASK ? last + 1 : 1;
}

/* The handle of serial number `serial` in the library that holds `anchor`. */
static inline uintptr_t state_handle(const void *anchor, uint64_t serial)
{
    const uint64_t tag = ((uint64_t)(uintptr_t)anchor >> 12) & STATE_TAG_MASK;
    return (uintptr_t)(STATE_MARK | (tag << STATE_SERIAL_BITS) | (serial & STATE_SERIAL_MASK));
}

/* 1 when `handle` is one the library that holds `anchor` issued, `last` being the last serial
 * number it issued (a live state or one freed since); 0 for anything else. */
static inline int state_issued_here(const void *anchor, const void *handle, uint64_t last)
{
    const uint64_t h = (uint64_t)(uintptr_t)handle, serial = h & STATE_SERIAL_MASK;
    return (h & ~STATE_SERIAL_MASK) == ((uint64_t)state_handle(anchor, 0) & ~STATE_SERIAL_MASK) &&
           serial >= 1 && serial <= last;
}

#endif
