"""The distribution's packages, from the component registry (``cosim/components.toml``):
each registered component's folder installs as the import package ``glider_<name>``, so
that adding a component is one folder and one registry line
(docs/how-to/add-a-component.md). Everything else is in pyproject.toml."""

import importlib.util
import sys
from pathlib import Path

from setuptools import find_packages, setup

ROOT = Path(__file__).resolve().parent
# the registry's reader, loaded from its file: the package is not installed yet
_spec = importlib.util.spec_from_file_location("_components", ROOT / "cosim" / "components.py")
components = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = components  # its dataclasses look their module up
_spec.loader.exec_module(components)

package_dir = components.package_dirs()
packages = [name for name in package_dir if name != "glider_cosim"]
packages += ["glider_cosim", *(f"glider_cosim.{p}" for p in find_packages(str(ROOT / "cosim")))]
# what the wheel needs besides the modules: each component's C sources, readme,
# reference CSVs, component.toml and FMI-LS-REF folder (lsref/, packed into its FMUs);
# the FMI runtime's C sources; the fast loop's and helpers' C sources, the registry, the
# shipped scenarios and the verification kit
package_data = {
    name: ["*.md", "*.csv", "*.c", "*.h", "*.toml", "lsref/*", "lsref/*/*"] for name in package_dir
}
package_data["glider_fmi"] = ["*.md", "*.c", "*.h", "wasm/*.c", "wasm/wit/*.wit"]
package_data["glider_cosim"] = [
    "components.toml",
    "verification/*/*.csv",
    "verification/*/*.opt",
    "verification/*/README.md",
    # FMI-LS-REF: the vendored schemas (each component's folder is in its package)
    "verification/schemas/*",
]
package_data.update(
    {
        "glider_cosim.master": ["*.c", "*.h"],
        "glider_cosim.runner": ["*.c", "*.js"],
        "glider_cosim.interop": ["*.c"],
        "glider_cosim.realtime": ["*.c"],
        "glider_cosim.scenarios": ["*.toml"],
    }
)

setup(package_dir=package_dir, packages=packages, package_data=package_data)
