"""Built-in worlds: terrain, ground materials, vegetation and sky of eight outdoor environments.

They stand in for the Unreal environments of the paper (savanna, grasslands, meadow, woodland,
moorlands, an Icelandic highland, dry Australian scrub, fields with windmills). Every number is a
physical quantity: metres, degrees, instances per hectare. Heights in material and vegetation bands
are map-frame z (ENU, metres); every preset terrain is shifted so that its flat central zone — where
zebras stand — averages z = 0. Colours are stored as linear RGB 0..1 (what USD ``displayColor`` and
renderers expect) and authored as sRGB through :func:`srgb`; tints are linear factors.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from zebra_sim_ros.errors import ParameterError

Rgb = tuple[float, float, float]
INF = float("inf")


def srgb(r: float, g: float, b: float) -> Rgb:
    """Linear RGB of an sRGB-encoded colour (how colours are picked by eye), for authoring presets."""

    def lin(c: float) -> float:
        return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4

    return (round(lin(r), 4), round(lin(g), 4), round(lin(b), 4))


STYLES = {"acacia": "tree", "deciduous": "tree", "conifer": "tree", "bush": "bush", "rock": "rock",
          "mound": "rock", "tuft": "grass", "fence": "prop", "wall": "prop", "trough": "prop", "hut": "prop",
          "vehicle": "prop", "person": "prop"}
PATTERNS = ("uniform", "clustered", "gradient", "hedgerow")
MATERIAL_PATTERNS = ("noise", "fields", "canopy", "tracks")


@dataclass(frozen=True)
class TerrainSpec:
    """How to synthesise the heightfield (see :func:`zebra_sim_ros.world.noise.spectral_noise`).

    The terrain is a square of ``size_m`` centred on the map origin, sampled every ``resolution`` m.
    ``relief_m`` is the standard deviation of the fractal heights before the central zone is flattened.
    """

    size_m: float = 512.0
    resolution: float = 1.0
    relief_m: float = 3.0
    exponent: float = 3.0
    min_wavelength_m: float = 4.0
    max_wavelength_m: float = 300.0
    ridges: float = 0.0  # 0..1: share of ridged (sharp-crested) noise in the relief
    gully_depth_m: float = 0.0  # depth of winding erosion channels, 0 = none
    gully_width_m: float = 8.0
    gully_wavelength_m: float = 160.0  # spacing of the channels
    valley_depth_m: float = 0.0  # how far the sides of one broad valley through the centre rise
    valley_width_m: float = 160.0
    flat_zone_m: float = 340.0  # side of the central square where relief is damped; zebras stand here
    flat_factor: float = 0.4  # relief multiplier inside that square (1 = no flattening)
    flat_transition_m: float = 60.0
    basin_depth_m: float = 0.0  # a waterhole: a bowl this deep, off the centre of the flat zone (0 = none)
    basin_radius_m: float = 45.0
    water_fill: float = 0.0  # 0..1: the basin's water level as a share of its depth (0 = dry)


@dataclass(frozen=True)
class MaterialLayer:
    """One ground material, painted over the layers before it where its rules hold.

    Rules: map-frame z inside ``height_band`` (metres, edges blurred by ``height_soft_m`` and jittered by
    noise), slope inside ``slope_band`` (degrees, blurred by ``slope_soft_deg``), and — if ``coverage`` < 1 —
    inside noise patches of about ``patch_scale_m`` covering that fraction of the ground. ``pattern``
    "fields" colours each farm field (mean side ``patch_scale_m``) from ``palette``; "canopy" covers the
    ground under and around trees (forest floor, shade-dried soil); "tracks" paints pairs of wheel ruts
    ``track_width_m`` apart along winding lines about ``patch_scale_m`` apart. The texture is value noise of grain
    ``noise_scale_m`` changing brightness by +-``contrast``.
    """

    name: str
    rgb: Rgb
    noise_scale_m: float = 6.0
    contrast: float = 0.12
    height_band: tuple[float, float] = (-INF, INF)
    slope_band: tuple[float, float] = (0.0, 90.0)
    height_soft_m: float = 2.0
    slope_soft_deg: float = 3.0
    coverage: float = 1.0
    patch_scale_m: float = 60.0
    pattern: str = "noise"
    palette: tuple[Rgb, ...] = ()
    opacity: float = 1.0  # < 1 lets the layers below show through (sparse flowers in grass)
    track_width_m: float = 1.7


@dataclass(frozen=True)
class VegetationLayer:
    """One scattered population (trees, bushes, rocks or grass tufts) of one style.

    ``per_hectare`` is the mean density (for "gradient": inside the dense forest; for "hedgerow" the
    instances sit every ``hedge_spacing_m`` along field boundaries instead). ``scale`` is the uniform
    scale range applied to the prototype (whose size at scale 1 is set in vegetation.py); instances keep
    ``min_spacing_m`` apart, avoid slopes over ``max_slope_deg`` and z outside ``height_band``.
    """

    kind: str
    style: str
    per_hectare: float
    scale: tuple[float, float] = (0.8, 1.2)
    min_spacing_m: float = 0.0
    max_slope_deg: float = 35.0
    height_band: tuple[float, float] = (-INF, INF)
    pattern: str = "uniform"
    cluster_scale_m: float = 60.0  # clumps for "clustered"; width of the forest edge for "gradient"
    tint: Rgb = (1.0, 1.0, 1.0)
    variants: int = 3
    hedge_spacing_m: float = 0.0


@dataclass(frozen=True)
class Sky:
    """Sky dome and atmosphere: colours (linear RGB 0..1), haze extinction per metre, light scales."""

    zenith_rgb: Rgb = srgb(0.30, 0.50, 0.85)
    horizon_rgb: Rgb = srgb(0.78, 0.84, 0.92)
    haze_per_m: float = 0.0004
    ambient: float = 0.35
    sun: float = 1.0


@dataclass(frozen=True)
class WorldPreset:
    """A built-in world: everything :func:`zebra_sim_ros.world.world.generate_world` needs besides a seed."""

    name: str
    description: str
    terrain: TerrainSpec
    materials: tuple[MaterialLayer, ...]
    vegetation: tuple[VegetationLayer, ...]
    sky: Sky = field(default_factory=Sky)
    max_slope_deg: float = 25.0  # steepest ground a zebra may stand on
    margin_m: float = 30.0  # placeable area keeps this far from the terrain edge

    def __post_init__(self) -> None:
        t = self.terrain
        if t.size_m < 64 or t.resolution <= 0 or t.size_m / t.resolution > 4096:
            raise ParameterError(f"{self.name}.terrain", (t.size_m, t.resolution), "size >= 64 m, <= 4096 samples")
        if not self.materials or self.materials[0].coverage < 1 or self.materials[0].pattern != "noise":
            raise ParameterError(f"{self.name}.materials", self.materials[:1], "a first layer covering everything")
        for m in self.materials:
            if m.pattern not in MATERIAL_PATTERNS or not 0 <= m.coverage <= 1:
                raise ParameterError(f"{self.name}.materials.{m.name}", (m.pattern, m.coverage),
                                     f"pattern in {MATERIAL_PATTERNS}, coverage 0..1")
            if m.pattern == "fields" and not m.palette:
                raise ParameterError(f"{self.name}.materials.{m.name}.palette", m.palette, "colours for the fields")
        for v in self.vegetation:
            if STYLES.get(v.style) != v.kind or v.pattern not in PATTERNS or v.per_hectare < 0:
                raise ParameterError(f"{self.name}.vegetation.{v.style}", (v.kind, v.style, v.pattern),
                                     f"a style of its kind {STYLES}, pattern in {PATTERNS}, density >= 0")
            if v.pattern == "hedgerow" and (v.hedge_spacing_m <= 0 or self.fields_layer() is None):
                raise ParameterError(f"{self.name}.vegetation.{v.style}.hedge_spacing_m", v.hedge_spacing_m,
                                     "> 0 m, with a 'fields' material layer to follow")

    def fields_layer(self) -> MaterialLayer | None:
        """The material layer laying out farm fields, if any (hedgerows follow its boundaries)."""
        return next((m for m in self.materials if m.pattern == "fields"), None)


PRESETS: dict[str, WorldPreset] = {
    "savanna": WorldPreset(
        name="savanna",
        description="flat golden grass plain with umbrella acacias, a few bushes and termite mounds",
        terrain=TerrainSpec(relief_m=2.5, exponent=4.3, min_wavelength_m=6.0, max_wavelength_m=320.0,
                            flat_zone_m=380.0, flat_factor=0.45),
        materials=(
            MaterialLayer("golden_grass", srgb(0.74, 0.62, 0.36), noise_scale_m=4.0, contrast=0.10),
            MaterialLayer("pale_grass", srgb(0.82, 0.74, 0.50), coverage=0.35, patch_scale_m=70.0),
            MaterialLayer("green_grass", srgb(0.52, 0.53, 0.28), coverage=0.18, patch_scale_m=45.0),
            MaterialLayer("shade_soil", srgb(0.55, 0.45, 0.30), pattern="canopy", coverage=0.6, contrast=0.15),
            MaterialLayer("red_soil", srgb(0.62, 0.44, 0.30), coverage=0.06, patch_scale_m=18.0, contrast=0.18),
            MaterialLayer("bank_soil", srgb(0.60, 0.45, 0.32), slope_band=(14.0, 90.0)),
        ),
        vegetation=(
            VegetationLayer("tree", "acacia", 1.8, scale=(0.7, 1.3), min_spacing_m=14.0, max_slope_deg=20.0,
                            pattern="clustered", cluster_scale_m=90.0),
            VegetationLayer("bush", "bush", 5.0, scale=(0.7, 1.4), min_spacing_m=3.0, pattern="clustered",
                            cluster_scale_m=50.0, tint=(0.95, 0.95, 0.75)),
            VegetationLayer("rock", "mound", 1.2, scale=(0.6, 1.5), min_spacing_m=10.0),
            VegetationLayer("rock", "rock", 0.4, scale=(0.4, 1.0), min_spacing_m=4.0),
            VegetationLayer("grass", "tuft", 1800.0, scale=(0.8, 1.5), tint=(1.25, 1.05, 0.70)),
        ),
        sky=Sky(srgb(0.28, 0.48, 0.85), srgb(0.85, 0.84, 0.80), 0.0005, 0.33, 1.05),
        max_slope_deg=25.0,
    ),
    "grassland": WorldPreset(
        name="grassland",
        description="rolling green and yellow grass hills with few trees",
        terrain=TerrainSpec(relief_m=7.0, exponent=4.3, min_wavelength_m=10.0, max_wavelength_m=420.0,
                            flat_zone_m=340.0, flat_factor=0.5),
        materials=(
            MaterialLayer("green_grass", srgb(0.42, 0.56, 0.24), noise_scale_m=5.0),
            MaterialLayer("yellow_grass", srgb(0.70, 0.67, 0.34), coverage=0.40, patch_scale_m=90.0),
            MaterialLayer("dark_grass", srgb(0.30, 0.45, 0.18), coverage=0.20, patch_scale_m=35.0),
            MaterialLayer("dry_slope", srgb(0.62, 0.58, 0.36), slope_band=(16.0, 90.0)),
        ),
        vegetation=(
            VegetationLayer("tree", "deciduous", 0.5, scale=(0.7, 1.2), min_spacing_m=12.0, pattern="clustered",
                            cluster_scale_m=80.0),
            VegetationLayer("bush", "bush", 3.0, scale=(0.6, 1.2), min_spacing_m=3.0, pattern="clustered"),
            VegetationLayer("rock", "rock", 0.4, scale=(0.4, 1.2), min_spacing_m=4.0),
            VegetationLayer("grass", "tuft", 2000.0, scale=(0.8, 1.6), tint=(0.95, 1.05, 0.85)),
        ),
        sky=Sky(srgb(0.26, 0.46, 0.88), srgb(0.76, 0.84, 0.94), 0.0004, 0.35, 1.0),
        max_slope_deg=25.0,
    ),
    "meadow": WorldPreset(
        name="meadow",
        description="lush green meadow with flower patches and scattered deciduous trees",
        terrain=TerrainSpec(relief_m=4.0, exponent=4.2, min_wavelength_m=6.0, max_wavelength_m=360.0,
                            valley_depth_m=8.0, valley_width_m=200.0, flat_factor=0.5),
        materials=(
            MaterialLayer("lush_grass", srgb(0.28, 0.52, 0.16), noise_scale_m=4.0, contrast=0.14),
            MaterialLayer("light_grass", srgb(0.42, 0.62, 0.22), coverage=0.35, patch_scale_m=50.0),
            MaterialLayer("yellow_flowers", srgb(0.78, 0.74, 0.30), coverage=0.10, patch_scale_m=14.0, contrast=0.3,
                          noise_scale_m=1.5, opacity=0.45),
            MaterialLayer("purple_flowers", srgb(0.58, 0.44, 0.62), coverage=0.04, patch_scale_m=10.0, contrast=0.3,
                          noise_scale_m=1.5, opacity=0.4),
            MaterialLayer("white_flowers", srgb(0.80, 0.82, 0.74), coverage=0.04, patch_scale_m=8.0, contrast=0.3,
                          noise_scale_m=1.5, opacity=0.35),
            MaterialLayer("tree_shade", srgb(0.22, 0.40, 0.14), pattern="canopy", coverage=0.7),
        ),
        vegetation=(
            VegetationLayer("tree", "deciduous", 3.0, scale=(0.6, 1.2), min_spacing_m=8.0, pattern="clustered",
                            cluster_scale_m=70.0),
            VegetationLayer("bush", "bush", 8.0, scale=(0.6, 1.3), min_spacing_m=2.5, pattern="clustered",
                            cluster_scale_m=40.0, tint=(0.85, 1.1, 0.85)),
            VegetationLayer("rock", "rock", 0.2, scale=(0.3, 0.8), min_spacing_m=4.0),
            VegetationLayer("grass", "tuft", 2200.0, scale=(0.9, 1.8), tint=(0.80, 1.15, 0.75)),
        ),
        sky=Sky(srgb(0.24, 0.46, 0.90), srgb(0.74, 0.84, 0.96), 0.0003, 0.38, 1.0),
        max_slope_deg=25.0,
    ),
    "woodland": WorldPreset(
        name="woodland",
        description="forest edge: dense deciduous and conifer woods on one side fading into grassy clearings",
        terrain=TerrainSpec(relief_m=5.0, exponent=4.2, min_wavelength_m=6.0, max_wavelength_m=300.0,
                            flat_factor=0.5),
        materials=(
            MaterialLayer("clearing_grass", srgb(0.38, 0.50, 0.22), noise_scale_m=4.0),
            MaterialLayer("dry_grass", srgb(0.58, 0.56, 0.32), coverage=0.30, patch_scale_m=40.0),
            MaterialLayer("forest_floor", srgb(0.30, 0.25, 0.15), pattern="canopy", coverage=0.9, contrast=0.2),
            MaterialLayer("bare_bank", srgb(0.42, 0.36, 0.24), slope_band=(18.0, 90.0)),
        ),
        vegetation=(
            VegetationLayer("tree", "deciduous", 150.0, scale=(0.7, 1.3), min_spacing_m=5.0, pattern="gradient",
                            cluster_scale_m=70.0),
            VegetationLayer("tree", "conifer", 50.0, scale=(0.7, 1.3), min_spacing_m=4.0, pattern="gradient",
                            cluster_scale_m=70.0),
            VegetationLayer("bush", "bush", 50.0, scale=(0.6, 1.3), min_spacing_m=2.5, pattern="gradient",
                            cluster_scale_m=110.0, tint=(0.8, 1.0, 0.8)),
            VegetationLayer("rock", "rock", 1.0, scale=(0.4, 1.2), min_spacing_m=4.0),
            VegetationLayer("grass", "tuft", 1500.0, scale=(0.8, 1.5), tint=(0.9, 1.05, 0.85)),
        ),
        sky=Sky(srgb(0.30, 0.48, 0.80), srgb(0.74, 0.80, 0.86), 0.0006, 0.40, 0.95),
        max_slope_deg=25.0,
    ),
    "moorland": WorldPreset(
        name="moorland",
        description="rough heather moor in browns and purples with rocky outcrops and few trees",
        terrain=TerrainSpec(relief_m=9.0, exponent=4.0, min_wavelength_m=5.0, max_wavelength_m=300.0,
                            ridges=0.45, flat_factor=0.3, flat_zone_m=320.0),
        materials=(
            MaterialLayer("heather_brown", srgb(0.40, 0.29, 0.22), noise_scale_m=3.0, contrast=0.16),
            MaterialLayer("heather_purple", srgb(0.42, 0.30, 0.38), coverage=0.40, patch_scale_m=30.0, contrast=0.18),
            MaterialLayer("moor_grass", srgb(0.47, 0.45, 0.30), coverage=0.30, patch_scale_m=60.0),
            MaterialLayer("peat", srgb(0.24, 0.19, 0.15), height_band=(-INF, -4.0), height_soft_m=2.5, coverage=0.7,
                          patch_scale_m=25.0),
            MaterialLayer("scree", srgb(0.50, 0.49, 0.46), slope_band=(24.0, 90.0), slope_soft_deg=5.0, contrast=0.2),
        ),
        vegetation=(
            VegetationLayer("tree", "deciduous", 0.2, scale=(0.5, 0.9), min_spacing_m=15.0, max_slope_deg=22.0,
                            tint=(0.85, 0.95, 0.75)),
            VegetationLayer("rock", "rock", 8.0, scale=(0.4, 1.8), min_spacing_m=3.0, max_slope_deg=60.0,
                            pattern="clustered", cluster_scale_m=40.0),
            VegetationLayer("bush", "bush", 18.0, scale=(0.4, 0.9), min_spacing_m=2.0, pattern="clustered",
                            cluster_scale_m=35.0, tint=(1.15, 0.75, 1.05)),
            VegetationLayer("grass", "tuft", 1800.0, scale=(0.7, 1.3), tint=(1.1, 0.95, 0.75)),
        ),
        sky=Sky(srgb(0.40, 0.52, 0.72), srgb(0.80, 0.82, 0.84), 0.0008, 0.42, 0.85),
        max_slope_deg=24.0,
    ),
    "snowy_highland": WorldPreset(
        name="snowy_highland",
        description="Icelandic highland: snow above a height, rock on steep ground, tundra, sparse conifers",
        terrain=TerrainSpec(relief_m=14.0, exponent=4.1, min_wavelength_m=6.0, max_wavelength_m=340.0,
                            ridges=0.5, flat_factor=0.2, flat_zone_m=320.0, flat_transition_m=80.0),
        materials=(
            MaterialLayer("tundra", srgb(0.42, 0.42, 0.32), noise_scale_m=4.0, contrast=0.15),
            MaterialLayer("moss", srgb(0.36, 0.42, 0.24), coverage=0.30, patch_scale_m=40.0),
            MaterialLayer("gravel", srgb(0.48, 0.46, 0.42), coverage=0.25, patch_scale_m=25.0),
            MaterialLayer("snow_patches", srgb(0.88, 0.90, 0.94), coverage=0.15, patch_scale_m=20.0, contrast=0.05),
            MaterialLayer("snow", srgb(0.92, 0.94, 0.97), height_band=(3.0, INF), height_soft_m=4.0,
                          slope_band=(0.0, 34.0), slope_soft_deg=4.0, contrast=0.05),
            MaterialLayer("rock", srgb(0.38, 0.38, 0.40), slope_band=(30.0, 90.0), slope_soft_deg=5.0, contrast=0.2),
        ),
        vegetation=(
            VegetationLayer("tree", "conifer", 0.8, scale=(0.5, 1.1), min_spacing_m=8.0, max_slope_deg=22.0,
                            height_band=(-INF, 6.0), pattern="clustered", cluster_scale_m=60.0),
            VegetationLayer("rock", "rock", 6.0, scale=(0.5, 2.0), min_spacing_m=3.5, max_slope_deg=60.0,
                            pattern="clustered", cluster_scale_m=50.0, tint=(0.85, 0.87, 0.92)),
            VegetationLayer("bush", "bush", 1.0, scale=(0.4, 0.8), min_spacing_m=3.0, height_band=(-INF, 3.0),
                            tint=(0.9, 0.85, 0.7)),
            VegetationLayer("grass", "tuft", 700.0, scale=(0.6, 1.1), height_band=(-INF, 3.5),
                            tint=(1.15, 1.05, 0.85)),
        ),
        sky=Sky(srgb(0.50, 0.58, 0.70), srgb(0.82, 0.85, 0.89), 0.0012, 0.50, 0.70),
        max_slope_deg=22.0,
    ),
    "scrubland": WorldPreset(
        name="scrubland",
        description="dry red-brown outback soil with many bushes, dry grass and winding gullies",
        terrain=TerrainSpec(relief_m=4.0, exponent=4.2, min_wavelength_m=6.0, max_wavelength_m=280.0,
                            gully_depth_m=2.5, gully_width_m=7.0, gully_wavelength_m=170.0, flat_factor=0.45),
        materials=(
            MaterialLayer("red_soil", srgb(0.60, 0.36, 0.22), noise_scale_m=3.0, contrast=0.14),
            MaterialLayer("dry_grass", srgb(0.70, 0.58, 0.38), coverage=0.40, patch_scale_m=35.0),
            MaterialLayer("spinifex", srgb(0.55, 0.52, 0.34), coverage=0.15, patch_scale_m=15.0),
            MaterialLayer("gravel", srgb(0.66, 0.52, 0.40), coverage=0.10, patch_scale_m=20.0),
            MaterialLayer("gully_wall", srgb(0.48, 0.27, 0.17), slope_band=(12.0, 90.0), slope_soft_deg=4.0),
        ),
        vegetation=(
            VegetationLayer("tree", "acacia", 0.35, scale=(0.5, 0.8), min_spacing_m=15.0, max_slope_deg=18.0,
                            tint=(0.9, 0.9, 0.8)),
            VegetationLayer("bush", "bush", 45.0, scale=(0.5, 1.3), min_spacing_m=3.0, max_slope_deg=30.0,
                            pattern="clustered", cluster_scale_m=45.0, tint=(0.9, 0.95, 0.7)),
            VegetationLayer("rock", "rock", 4.0, scale=(0.3, 1.1), min_spacing_m=3.0, max_slope_deg=50.0,
                            tint=(1.1, 0.85, 0.75)),
            VegetationLayer("grass", "tuft", 1000.0, scale=(0.7, 1.3), tint=(1.3, 1.0, 0.7)),
        ),
        sky=Sky(srgb(0.22, 0.44, 0.86), srgb(0.86, 0.82, 0.76), 0.0005, 0.30, 1.1),
        max_slope_deg=25.0,
    ),
    "farmland": WorldPreset(
        name="farmland",
        description="flat patchwork of fields in greens, yellows and browns with hedgerows and lines of trees",
        terrain=TerrainSpec(relief_m=1.8, exponent=4.3, min_wavelength_m=8.0, max_wavelength_m=400.0,
                            flat_factor=0.7),
        materials=(
            MaterialLayer("pasture", srgb(0.40, 0.54, 0.24), noise_scale_m=5.0),
            MaterialLayer("fields", srgb(0.5, 0.5, 0.3), pattern="fields", patch_scale_m=110.0, contrast=0.08,
                          noise_scale_m=3.0,
                          palette=(srgb(0.36, 0.54, 0.20), srgb(0.50, 0.62, 0.28), srgb(0.78, 0.70, 0.38),
                                   srgb(0.48, 0.37, 0.25), srgb(0.68, 0.66, 0.42), srgb(0.30, 0.46, 0.18),
                                   srgb(0.60, 0.48, 0.30))),
            MaterialLayer("hedge_shade", srgb(0.26, 0.36, 0.16), pattern="canopy", coverage=0.5),
        ),
        vegetation=(
            VegetationLayer("bush", "bush", 0.0, scale=(0.8, 1.4), pattern="hedgerow", hedge_spacing_m=2.2,
                            tint=(0.8, 1.0, 0.8)),
            VegetationLayer("tree", "deciduous", 0.0, scale=(0.7, 1.2), pattern="hedgerow", hedge_spacing_m=22.0),
            VegetationLayer("tree", "deciduous", 0.3, scale=(0.7, 1.1), min_spacing_m=15.0),
            VegetationLayer("rock", "rock", 0.15, scale=(0.3, 0.8), min_spacing_m=5.0),
            VegetationLayer("grass", "tuft", 600.0, scale=(0.8, 1.4)),
        ),
        sky=Sky(srgb(0.30, 0.50, 0.86), srgb(0.78, 0.84, 0.92), 0.0005, 0.36, 1.0),
        max_slope_deg=25.0,
    ),
    "zoo": WorldPreset(
        name="zoo",
        description="zoo enclosures: raked sand and trodden grass in paddocks divided by fences and walls, shade "
                    "trees, water troughs, keepers' huts, vehicles and visitors",
        terrain=TerrainSpec(relief_m=0.8, exponent=4.3, min_wavelength_m=8.0, max_wavelength_m=300.0,
                            flat_factor=0.6),
        materials=(
            MaterialLayer("sand", srgb(0.76, 0.66, 0.50), noise_scale_m=3.0, contrast=0.10),
            MaterialLayer("paddocks", srgb(0.7, 0.6, 0.45), pattern="fields", patch_scale_m=70.0, contrast=0.10,
                          noise_scale_m=2.0,
                          palette=(srgb(0.78, 0.68, 0.52), srgb(0.70, 0.60, 0.44), srgb(0.50, 0.52, 0.30),
                                   srgb(0.62, 0.56, 0.40), srgb(0.82, 0.76, 0.62))),
            MaterialLayer("trodden", srgb(0.56, 0.47, 0.36), coverage=0.25, patch_scale_m=12.0, contrast=0.15),
            MaterialLayer("paths", srgb(0.62, 0.55, 0.45), pattern="tracks", patch_scale_m=60.0, track_width_m=1.2,
                          contrast=0.08),
            MaterialLayer("tree_shade", srgb(0.40, 0.36, 0.28), pattern="canopy", coverage=0.6),
        ),
        vegetation=(
            VegetationLayer("prop", "fence", 0.0, pattern="hedgerow", hedge_spacing_m=3.0, variants=2),
            VegetationLayer("prop", "wall", 0.0, pattern="hedgerow", hedge_spacing_m=3.0, variants=2,
                            max_slope_deg=20.0),
            VegetationLayer("tree", "deciduous", 0.8, scale=(0.7, 1.1), min_spacing_m=10.0, pattern="clustered",
                            cluster_scale_m=60.0),
            VegetationLayer("tree", "acacia", 0.4, scale=(0.6, 1.0), min_spacing_m=12.0),
            VegetationLayer("prop", "trough", 0.6, min_spacing_m=20.0),
            VegetationLayer("prop", "hut", 0.12, min_spacing_m=40.0, scale=(0.8, 1.2)),
            VegetationLayer("prop", "vehicle", 0.15, min_spacing_m=25.0, scale=(0.95, 1.05)),
            VegetationLayer("prop", "person", 0.5, scale=(0.95, 1.05), pattern="clustered", cluster_scale_m=40.0,
                            variants=5),
            VegetationLayer("bush", "bush", 3.0, scale=(0.5, 1.0), min_spacing_m=3.0, pattern="clustered"),
            VegetationLayer("rock", "rock", 0.3, scale=(0.4, 0.9), min_spacing_m=6.0),
            VegetationLayer("grass", "tuft", 400.0, scale=(0.6, 1.1), tint=(1.1, 1.05, 0.8)),
        ),
        sky=Sky(srgb(0.32, 0.50, 0.82), srgb(0.80, 0.83, 0.88), 0.0006, 0.38, 1.0),
        max_slope_deg=25.0,
    ),
    "waterhole": WorldPreset(
        name="waterhole",
        description="a waterhole on the savanna: open water that mirrors the sky, a ring of wet mud and trampled "
                    "soil, green grass near the shore, fever trees and bush",
        terrain=TerrainSpec(relief_m=2.0, exponent=4.3, min_wavelength_m=6.0, max_wavelength_m=300.0,
                            flat_zone_m=380.0, flat_factor=0.45, basin_depth_m=4.0, basin_radius_m=55.0,
                            water_fill=0.55),
        materials=(
            MaterialLayer("dry_grass", srgb(0.72, 0.62, 0.38), noise_scale_m=4.0, contrast=0.10),
            MaterialLayer("green_grass", srgb(0.45, 0.50, 0.24), height_band=(-INF, 0.2), height_soft_m=1.0),
            MaterialLayer("trampled", srgb(0.52, 0.43, 0.32), height_band=(-INF, -0.6), height_soft_m=0.8,
                          contrast=0.15),
            MaterialLayer("mud", srgb(0.30, 0.25, 0.19), height_band=(-INF, -1.5), height_soft_m=0.5, contrast=0.12),
            MaterialLayer("game_trails", srgb(0.55, 0.45, 0.33), pattern="tracks", patch_scale_m=45.0,
                          track_width_m=0.6, contrast=0.1, opacity=0.8),
        ),
        vegetation=(
            VegetationLayer("tree", "acacia", 2.5, scale=(0.7, 1.2), min_spacing_m=10.0, max_slope_deg=20.0,
                            pattern="clustered", cluster_scale_m=60.0, tint=(1.0, 1.05, 0.85)),
            VegetationLayer("bush", "bush", 8.0, scale=(0.6, 1.3), min_spacing_m=3.0, pattern="clustered",
                            cluster_scale_m=40.0),
            VegetationLayer("rock", "rock", 0.6, scale=(0.4, 1.0), min_spacing_m=5.0),
            VegetationLayer("grass", "tuft", 1600.0, scale=(0.8, 1.5), tint=(1.15, 1.05, 0.75)),
        ),
        sky=Sky(srgb(0.28, 0.48, 0.85), srgb(0.84, 0.84, 0.80), 0.0005, 0.34, 1.05),
        max_slope_deg=22.0,
    ),
    "bushland": WorldPreset(
        name="bushland",
        description="acacia bushland: dense thorn bush and small acacias over red-brown soil and tussock grass",
        terrain=TerrainSpec(relief_m=3.0, exponent=4.2, min_wavelength_m=6.0, max_wavelength_m=300.0,
                            flat_factor=0.5),
        materials=(
            MaterialLayer("tussock", srgb(0.66, 0.58, 0.38), noise_scale_m=3.0, contrast=0.14),
            MaterialLayer("red_soil", srgb(0.58, 0.38, 0.25), coverage=0.35, patch_scale_m=20.0, contrast=0.16),
            MaterialLayer("green_flush", srgb(0.46, 0.50, 0.26), coverage=0.15, patch_scale_m=30.0),
            MaterialLayer("under_bush", srgb(0.42, 0.33, 0.24), pattern="canopy", coverage=0.7),
        ),
        vegetation=(
            VegetationLayer("tree", "acacia", 12.0, scale=(0.45, 0.85), min_spacing_m=6.0, pattern="clustered",
                            cluster_scale_m=50.0, tint=(0.95, 1.0, 0.85)),
            VegetationLayer("bush", "bush", 70.0, scale=(0.6, 1.6), min_spacing_m=2.5, pattern="clustered",
                            cluster_scale_m=35.0, tint=(0.85, 0.9, 0.65)),
            VegetationLayer("rock", "mound", 0.8, scale=(0.6, 1.3), min_spacing_m=10.0),
            VegetationLayer("rock", "rock", 0.5, scale=(0.3, 0.9), min_spacing_m=4.0),
            VegetationLayer("grass", "tuft", 1500.0, scale=(0.7, 1.4), tint=(1.2, 1.0, 0.7)),
        ),
        sky=Sky(srgb(0.26, 0.46, 0.86), srgb(0.84, 0.82, 0.78), 0.0006, 0.33, 1.05),
        max_slope_deg=25.0,
    ),
    "dusty_plain": WorldPreset(
        name="dusty_plain",
        description="a dusty, overgrazed plain in the dry season: pale bare soil, sparse dry grass, vehicle and "
                    "game tracks, a few lone trees and a hazy sky",
        terrain=TerrainSpec(relief_m=1.5, exponent=4.4, min_wavelength_m=8.0, max_wavelength_m=400.0,
                            flat_factor=0.6),
        materials=(
            MaterialLayer("dust", srgb(0.76, 0.68, 0.55), noise_scale_m=5.0, contrast=0.08),
            MaterialLayer("dry_grass", srgb(0.72, 0.64, 0.45), coverage=0.35, patch_scale_m=30.0, contrast=0.12),
            MaterialLayer("darker_soil", srgb(0.60, 0.52, 0.42), coverage=0.2, patch_scale_m=60.0),
            MaterialLayer("vehicle_tracks", srgb(0.64, 0.56, 0.45), pattern="tracks", patch_scale_m=90.0,
                          track_width_m=1.8, contrast=0.06),
            MaterialLayer("game_tracks", srgb(0.66, 0.58, 0.47), pattern="tracks", patch_scale_m=35.0,
                          track_width_m=0.5, contrast=0.06, opacity=0.7),
        ),
        vegetation=(
            VegetationLayer("tree", "acacia", 0.3, scale=(0.6, 1.1), min_spacing_m=30.0, tint=(0.9, 0.9, 0.75)),
            VegetationLayer("bush", "bush", 1.5, scale=(0.4, 0.9), min_spacing_m=6.0, tint=(0.85, 0.85, 0.6)),
            VegetationLayer("prop", "vehicle", 0.12, min_spacing_m=60.0, scale=(0.95, 1.05)),
            VegetationLayer("rock", "rock", 0.4, scale=(0.3, 0.8), min_spacing_m=5.0, tint=(1.1, 1.0, 0.9)),
            VegetationLayer("grass", "tuft", 500.0, scale=(0.6, 1.1), tint=(1.3, 1.1, 0.75)),
        ),
        sky=Sky(srgb(0.45, 0.55, 0.72), srgb(0.86, 0.82, 0.74), 0.0012, 0.40, 0.95),
        max_slope_deg=25.0,
    ),
}

DEFAULT_PRESET = "savanna"


def get_preset(name: str) -> WorldPreset:
    """The built-in preset ``name``; :class:`ParameterError` naming 'world' and listing them otherwise."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ParameterError("world", name, f"one of {sorted(PRESETS)}") from None
