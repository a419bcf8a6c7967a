"""steer-envs: Gymnasium environments and wrappers for steering robot policies.

``import steer_envs`` registers every environment under the ``steer_envs/``
namespace, e.g. ``gymnasium.make("steer_envs/PolygonNav-4Mode-v0")``.
"""

from steer_envs.envs.registry import env_ids, register_all

__version__ = "0.1.0"

register_all()

__all__ = ["__version__", "env_ids", "register_all"]
