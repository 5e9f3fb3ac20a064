"""One simulation step: a scene in, the frames of its cameras with their exact labels out.

:meth:`Simulator.simulate` is place -> render -> label for ``generate`` and ``zebra-sim render``; the ROS graph runs
the same two halves in two processes: the camera node :meth:`Simulator.render` (its own camera), the labeller node
:class:`~zebra_sim_ros.labels.labeller.Labeller` on the masks and depth it receives. So a frame and its labels are
the same whichever front-end made them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zebra_sim_ros.labels.config import LabelFilters
from zebra_sim_ros.labels.labeller import Labeller
from zebra_sim_ros.messages import Labels, Scene
from zebra_sim_ros.rendering.effects import SensorModel
from zebra_sim_ros.rendering.renderer import RenderedView, Renderer, RenderOptions
from zebra_sim_ros.rendering.views import views_from_scene, zebras_from_scene
from zebra_sim_ros.world.world import World
from zebra_sim_ros.zebra.asset import ZebraLibrary


@dataclass
class Frame:
    """One camera's frame of a step: the rendered images (RGB, metric depth, instance ids) and its labels."""

    view: RenderedView
    labels: Labels


class Simulator:
    """The renderer of one world and, created on first use, the labeller sharing its GL context."""

    def __init__(self, world: World, library: ZebraLibrary, options: RenderOptions,
                 filters: LabelFilters | None = None, sensor: SensorModel | None = None) -> None:
        """``sensor``: the photograph's camera drawn per frame and view (seeded by the scene's seed, step and the
        camera's index, recorded in ``RenderedView.sensor``); None renders the clean image."""
        self.world, self.library = world, library
        self.sensor = sensor
        self.renderer = Renderer(world, library, options)
        self.filters = filters or LabelFilters()
        self._labeller: Labeller | None = None

    @property
    def labeller(self) -> Labeller:
        if self._labeller is None:
            self._labeller = Labeller(self.library, self.renderer.camera, self.filters,
                                      self.renderer.options.zebra_detail_distance_m, ctx=self.renderer.ctx)
        return self._labeller

    def render(self, scene: Scene, names: list[str] | None = None) -> list[RenderedView]:
        """The views of the scene's cameras (all, or those named)."""
        views = self.renderer.render(zebras_from_scene(scene, self.library), scene.lighting,
                                     views_from_scene(scene, names), scene.ground, scene.weather)
        if self.sensor is not None:
            order = [c.name for c in scene.cameras]
            for v in views:
                rng = np.random.default_rng([scene.seed, scene.step, order.index(v.name), 0x5E50])
                v.sensor = self.sensor.draw(rng)
                v.rgb = self.sensor.apply(v.rgb, v.sensor, rng)
        return views

    def simulate(self, scene: Scene, names: list[str] | None = None) -> list[Frame]:
        """Render the scene's cameras (all, or those named) and label every frame."""
        return [Frame(v, self.labeller.label(scene, v.name, v.instances, v.depth)) for v in self.render(scene, names)]

    def release(self) -> None:
        """Release the GL resources."""
        if self._labeller is not None:
            self._labeller.release()
            self._labeller = None
        self.renderer.release()
