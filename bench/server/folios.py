#!/usr/bin/env python3
"""How the pages holding tile bytes are grouped into folios (needs root: /proc/kpageflags).

  folios.py file PATH...   the page cache pages of each file (as nginx sends them)
  folios.py proc PID       vtex's sealed tiles: its read-only anonymous mappings of 100 KB–4 MiB

Per file or mapping: pages, compound (large-folio) head and tail pages, and how many pages
sit physically right after their predecessor. Every distinct folio is one `struct page`
reference count that the server's and the client's cores both write per tile sent, so
fewer, larger folios per tile cost the client less kernel time on loopback.
"""
import ctypes
import os
import struct
import sys

HEAD, TAIL = 1 << 15, 1 << 16


def page_flags(pfns):
    with open('/proc/kpageflags', 'rb') as f:
        out = []
        for p in pfns:
            f.seek(p * 8)
            out.append(struct.unpack('<Q', f.read(8))[0])
        return out


def pfns_of(pid, addr, n):
    with open(f'/proc/{pid}/pagemap', 'rb') as f:
        f.seek((addr // 4096) * 8)
        entries = struct.unpack(f'<{n}Q', f.read(8 * n))
    return [e & ((1 << 55) - 1) for e in entries if e >> 63]


def summary(name, pfns):
    flags = page_flags(pfns)
    heads = sum(1 for x in flags if x & HEAD)
    tails = sum(1 for x in flags if x & TAIL)
    folios = len(pfns) - tails
    contiguous = sum(1 for a, b in zip(pfns, pfns[1:]) if b == a + 1)
    print(f'{name}: {len(pfns)} pages in {folios} folios ({heads} large: {heads + tails} pages), '
          f'{contiguous}/{max(len(pfns) - 1, 0)} pages physically after their predecessor')


def files(paths):
    libc = ctypes.CDLL(None)
    libc.mmap.restype = ctypes.c_void_p
    libc.mmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_long]
    for path in paths:
        fd = os.open(path, os.O_RDONLY)
        size = os.fstat(fd).st_size
        addr = libc.mmap(None, size, 1, 1, fd, 0)  # PROT_READ, MAP_SHARED
        view = (ctypes.c_char * size).from_address(addr)
        for i in range(0, size, 4096):
            view[i]  # fault every page in
        summary(path, pfns_of(os.getpid(), addr, (size + 4095) // 4096))
        os.close(fd)


def process(pid):
    for line in open(f'/proc/{pid}/maps'):
        parts = line.split()
        start, end = (int(x, 16) for x in parts[0].split('-'))
        if parts[1] == 'r--p' and len(parts) == 5 and 100_000 < end - start <= 4 << 20:
            summary(parts[0], pfns_of(pid, start, (end - start) // 4096))


if __name__ == '__main__':
    if len(sys.argv) >= 3 and sys.argv[1] == 'file':
        files(sys.argv[2:])
    elif len(sys.argv) == 3 and sys.argv[1] == 'proc':
        process(int(sys.argv[2]))
    else:
        sys.exit(__doc__)
