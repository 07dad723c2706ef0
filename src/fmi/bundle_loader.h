/* The Python that imports a Python FMU's slave from its own resources/ only.
 *
 * One definition, two users: the back end runs it to find the slave class
 * (backend_python.c), and the probe of a candidate Python in a host without one runs it
 * to check that Python can import the slave (python_find.c).
 *
 * glider_load(resources, module, cls) gives the FMU's resources/ a package of its own,
 * named after the SHA-256 of the code it holds (every .py file and slavemodule.txt, by
 * relative path), imports <package>.<module> and returns its attribute cls (None if it
 * has none). Nothing is
 * put on sys.path: the bundled code imports its own modules relatively (made so at build
 * time, glider_fmi/bundle.py), so neither the host's modules nor another FMU's can stand
 * in for the FMU's, and the FMU's never replace the host's. Two FMUs holding the same
 * code share one package (the same code, imported once per process); a package whose
 * folder was deleted since (fmpy removes an FMU's unpacked folder when it is done) is
 * pointed at the new folder before anything more is imported from it.
 */
#ifndef GLIDER_BUNDLE_LOADER_H
#define GLIDER_BUNDLE_LOADER_H

/* a string literal, so that the probe can be written around it */
#define GLIDER_BUNDLE_LOADER \
    "def glider_load(resources, module, cls):\n" \
    "    import hashlib, importlib, importlib.machinery, importlib.util, os, sys\n" \
    "    resources = os.path.abspath(resources)\n" \
    "    h = hashlib.sha256()\n" \
    "    for root, dirs, files in os.walk(resources):\n" \
    "        dirs[:] = sorted(d for d in dirs if d != '__pycache__')\n" \
    "        for f in sorted(files):\n" \
    "            if f.endswith('.py') or (root == resources and f == 'slavemodule.txt'):\n" \
    "                p = os.path.join(root, f)\n" \
    "                with open(p, 'rb') as fh:\n" \
    "                    data = fh.read()\n" \
    "                rel = os.path.relpath(p, resources).replace(os.sep, '/').encode()\n" \
    "                h.update(b'%d:%s:%d:' % (len(rel), rel, len(data)))\n" \
    "                h.update(data)\n" \
    "    name = '_glider_fmu_' + h.hexdigest()[:32]\n" \
    "    pkg = sys.modules.get(name)\n" \
    "    if pkg is None:\n" \
    "        spec = importlib.machinery.ModuleSpec(name, None, is_package=True)\n" \
    "        spec.submodule_search_locations = [resources]\n" \
    "        pkg = importlib.util.module_from_spec(spec)\n" \
    "        sys.modules[name] = pkg\n" \
    "    else:\n" \
    "        old = pkg.__path__[0]\n" \
    "        if old != resources and not os.path.isdir(old):\n" \
    "            for key, m in list(sys.modules.items()):\n" \
    "                if key == name or key.startswith(name + '.'):\n" \
    "                    path = getattr(m, '__path__', None)\n" \
    "                    if isinstance(path, list):\n" \
    "                        path[:] = [resources + p[len(old):] if p.startswith(old) else p\n" \
    "                                   for p in path]\n" \
    "    return getattr(importlib.import_module(name + '.' + module), cls, None)\n"

#endif
