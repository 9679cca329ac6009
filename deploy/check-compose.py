#!/usr/bin/env python3
"""Checks a docker-compose file without an engine: every service's command must be a valid
invocation of the built binaries. Runs `docker-compose config` (which validates the file and
resolves variables and paths), then each service's command with --check-config, the binary
taken from BUILD_DIR, bind-mount targets mapped to their sources on this machine and named
volumes to a scratch directory. Services run in the order their depends_on gives; the image's
`sirad-make-keys` is deploy/make-keys.sh (it makes the keys the others then check).
    deploy/check-compose.py BUILD_DIR deploy/docker-compose.yml [PROJECT_DIR]
    deploy/check-compose.py --root ROOTFS deploy/docker-compose.yml [PROJECT_DIR]
PROJECT_DIR (default: the compose file's folder) anchors its relative paths. With --root
(as root; deploy/image-check.sh), the commands are the image's own: each runs in a chroot of
the image's root file system ROOTFS, its mounts bound there at their targets, as the engine
would mount them.
"""
import os
import shlex
import subprocess
import sys
import tempfile

import yaml  # python3-yaml, a dependency of Debian's docker-compose


def ordered(services):
    """Service names, each after those it depends on."""
    done, out = set(), []
    def visit(name, path):
        if name in done:
            return
        if name in path:
            sys.exit(f"depends_on cycle through {name}")
        depends = services[name].get("depends_on", {})
        for dep in (depends if isinstance(depends, (list, dict)) else []):
            visit(dep, path | {name})
        done.add(name)
        out.append(name)
    for name in services:
        visit(name, set())
    return out


def run_in_root(root, mounts, args):
    """Runs args in a chroot of root with each (target, source) mount bound at its target."""
    bound = []
    try:
        for target, source in mounts:
            where = os.path.join(root, target.lstrip("/"))
            os.makedirs(where, exist_ok=True)
            subprocess.run(["mount", "--bind", source, where], check=True)
            bound.append(where)
        return subprocess.run(["chroot", root] + args, capture_output=True, text=True, cwd="/")
    finally:
        for where in reversed(bound):
            subprocess.run(["umount", where], check=False)


def main():
    argv = sys.argv[1:]
    root = None
    if argv[:1] == ["--root"] and len(argv) >= 2:
        root, argv = os.path.abspath(argv[1]), argv[2:]
        argv = [None] + argv
    if len(argv) not in (2, 3):
        sys.exit("usage: check-compose.py (BUILD_DIR | --root ROOTFS) COMPOSE_FILE [PROJECT_DIR]")
    build = os.path.abspath(argv[0]) if argv[0] else None
    compose = argv[1]
    project = argv[2] if len(argv) == 3 else os.path.dirname(os.path.abspath(compose))
    resolved = subprocess.run(["docker-compose", "-f", compose, "--project-directory", project, "config"],
                              check=True, capture_output=True, text=True).stdout
    services = yaml.safe_load(resolved)["services"]
    scratch = tempfile.mkdtemp(prefix="sirad-compose-")
    failed = 0
    for name in ordered(services):
        service = services[name]
        command = service.get("command")
        if command is None:
            print(f"{name}: no command", file=sys.stderr)
            failed += 1
            continue
        args = shlex.split(command) if isinstance(command, str) else list(command)
        mounts = []
        for volume in service.get("volumes", []):
            if isinstance(volume, str):
                parts = volume.split(":")
                volume = {"type": "bind" if parts[0].startswith(("/", ".")) else "volume",
                          "source": parts[0], "target": parts[1]}
            if volume["type"] == "bind":
                source = volume["source"]
            else:
                source = os.path.join(scratch, volume["source"])
                os.makedirs(source, exist_ok=True)
            mounts.append((volume["target"].rstrip("/"), source))
        def local(arg):
            for target, source in mounts:
                if arg == target or arg.startswith(target + "/"):
                    return source + arg[len(target):]
            return arg
        env = dict(os.environ)
        if root:
            result = run_in_root(root, mounts, args + ([] if args[0] == "sirad-make-keys" else ["--check-config"]))
        elif args[0] == "sirad-make-keys":
            run = [os.path.join(os.path.dirname(os.path.abspath(__file__)), "make-keys.sh")] + [local(a) for a in args[1:]]
            env["SIRAD"] = os.path.join(build, "sirad")
            result = subprocess.run(run, capture_output=True, text=True, env=env)
        else:
            binary = os.path.join(build, args[0])
            if not os.access(binary, os.X_OK):
                print(f"{name}: {args[0]} is not a sirad binary in {build}", file=sys.stderr)
                failed += 1
                continue
            run = [binary] + [local(a) for a in args[1:]] + ["--check-config"]
            result = subprocess.run(run, capture_output=True, text=True, env=env)
        out = (result.stdout + result.stderr).strip()
        print(f"{name}: {out}")
        if result.returncode != 0:
            print(f"{name}: command failed: {' '.join(shlex.quote(a) for a in args)}", file=sys.stderr)
            failed += 1
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
