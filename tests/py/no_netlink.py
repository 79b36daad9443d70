"""Runs a command with netlink sockets refused, as systemd's RestrictAddressFamilies refuses an
address family it does not list (socket() fails with EAFNOSUPPORT). Needs libseccomp's Python
binding (Debian python3-seccomp). Usage: no_netlink.py COMMAND [ARG...]"""
import errno
import os
import sys

import seccomp

AF_NETLINK = 16

f = seccomp.SyscallFilter(defaction=seccomp.ALLOW)
f.add_rule(seccomp.ERRNO(errno.EAFNOSUPPORT), "socket", seccomp.Arg(0, seccomp.EQ, AF_NETLINK))
f.load()
os.execvp(sys.argv[1], sys.argv[1:])
