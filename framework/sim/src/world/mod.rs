//! Procedural worlds, generated deterministically from a kind and a seed.
//!
//! A world is a terrain height field (surface worlds) plus a BVH over every object's triangles, and
//! the drivable [`RoadGraph`] that routes walk on. See the `planetary`, `cave` and `urban` modules for
//! what each kind contains (`blocks` is the urban generator's self-similar layout).

mod cave;
pub mod graph;
pub mod lanes;
mod planetary;
pub mod rocks;
pub mod shapes;
mod urban;

use std::fmt;
use std::str::FromStr;
use std::sync::{Arc, Mutex};

use serde::{Deserialize, Serialize};

pub use graph::RoadGraph;

use crate::SimError;
use crate::bvh::Bvh;
use crate::geometry::{Ray, V3};
use crate::heightfield::HeightField;

/// The kinds of world the simulator generates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WorldKind {
    /// Rolling fractal terrain with craters, ridges and rocks; almost no tall structure.
    Planetary,
    /// A branching network of irregular tunnels with junction chambers.
    Cave,
    /// A street grid with buildings, poles, parked cars and trees.
    Urban,
    /// A regular street grid of identical blocks and identically lined streets: a city that aliases.
    Blocks,
}

impl WorldKind {
    pub const ALL: [WorldKind; 4] = [
        WorldKind::Planetary,
        WorldKind::Cave,
        WorldKind::Urban,
        WorldKind::Blocks,
    ];

    pub const fn name(self) -> &'static str {
        match self {
            WorldKind::Planetary => "planetary",
            WorldKind::Cave => "cave",
            WorldKind::Urban => "urban",
            WorldKind::Blocks => "blocks",
        }
    }
}

impl fmt::Display for WorldKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for WorldKind {
    type Err = SimError;

    fn from_str(name: &str) -> Result<Self, SimError> {
        Self::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(name.trim()))
            .ok_or_else(|| SimError::UnknownWorld {
                name: name.to_owned(),
                known: Self::ALL.iter().map(|k| k.name().to_owned()).collect(),
            })
    }
}

/// Surface materials; the albedo drives simulated intensity.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Material {
    Regolith = 0,
    Rock = 1,
    Asphalt = 2,
    Concrete = 3,
    Facade = 4,
    CarPaint = 5,
    Bark = 6,
    Foliage = 7,
    Grass = 8,
    CaveRock = 9,
    Metal = 10,
}

impl Material {
    const ALL: [Material; 11] = [
        Material::Regolith,
        Material::Rock,
        Material::Asphalt,
        Material::Concrete,
        Material::Facade,
        Material::CarPaint,
        Material::Bark,
        Material::Foliage,
        Material::Grass,
        Material::CaveRock,
        Material::Metal,
    ];

    /// The material with index `index` (unknown indices read as rock).
    pub fn from_index(index: u8) -> Self {
        Self::ALL
            .get(usize::from(index))
            .copied()
            .unwrap_or(Material::Rock)
    }

    /// Diffuse reflectivity at 905 nm, roughly after published LiDAR reflectivity tables.
    pub const fn albedo(self) -> f32 {
        match self {
            Material::Regolith => 0.32,
            Material::Rock => 0.24,
            Material::Asphalt => 0.10,
            Material::Concrete => 0.45,
            Material::Facade => 0.35,
            Material::CarPaint => 0.55,
            Material::Bark => 0.30,
            Material::Foliage => 0.50,
            Material::Grass => 0.40,
            Material::CaveRock => 0.20,
            Material::Metal => 0.70,
        }
    }
}

/// The closest surface a ray meets.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub range_m: f32,
    /// Unit surface normal (either side).
    pub normal: V3,
    pub material: Material,
}

/// A generated world.
pub struct World {
    kind: WorldKind,
    seed: u64,
    terrain: Option<HeightField>,
    objects: Bvh,
    graph: RoadGraph,
    /// Lower and upper x/y corner of the region worth previewing.
    extent_m: [f64; 4],
}

impl fmt::Debug for World {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("World")
            .field("kind", &self.kind)
            .field("seed", &self.seed)
            .field("triangles", &self.objects.mesh().len())
            .field("junctions", &self.graph.nodes.len())
            .finish()
    }
}

/// Recently used worlds, most recent last; a few are kept alive so that robots, tools and tests that
/// ask again do not pay for generation twice.
type CacheEntry = ((WorldKind, u64, u32), Arc<World>);
static CACHE: Mutex<Vec<CacheEntry>> = Mutex::new(Vec::new());
const CACHED_WORLDS: usize = 3;

impl World {
    /// Generates the world of `kind` for `seed`. The same arguments always give the same world.
    pub fn generate(kind: WorldKind, seed: u64) -> Self {
        Self::generate_in_season(kind, seed, 0)
    }

    /// The world of `kind` for `seed` in `season`: season 0 is the world as generated; in any other,
    /// loose objects have changed (the planetary world's rocks: 15 % gone, 30 % moved 0.5–3 m), while
    /// the terrain and the roads stay. Other worlds have no seasons yet and are the same in every one.
    pub fn generate_in_season(kind: WorldKind, seed: u64, season: u32) -> Self {
        let parts = match kind {
            WorldKind::Planetary => planetary::generate(seed, season),
            WorldKind::Cave => cave::generate(seed),
            WorldKind::Urban => urban::generate(seed, urban::Layout::Irregular),
            WorldKind::Blocks => urban::generate(seed, urban::Layout::IdenticalBlocks),
        };
        Self {
            kind,
            seed,
            terrain: parts.terrain,
            objects: Bvh::build(parts.objects),
            graph: parts.graph,
            extent_m: parts.extent_m,
        }
    }

    /// The world of `kind` for `seed`, shared with every other holder in the process (robots of one
    /// fleet build it once).
    pub fn shared(kind: WorldKind, seed: u64) -> Arc<Self> {
        Self::shared_in_season(kind, seed, 0)
    }

    /// [`World::shared`] in `season` (see [`World::generate_in_season`]).
    pub fn shared_in_season(kind: WorldKind, seed: u64, season: u32) -> Arc<Self> {
        let mut cache = CACHE.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(index) = cache.iter().position(|(key, _)| *key == (kind, seed, season)) {
            let entry = cache.remove(index);
            let world = Arc::clone(&entry.1);
            cache.push(entry);
            return world;
        }
        let world = Arc::new(Self::generate_in_season(kind, seed, season));
        cache.push(((kind, seed, season), Arc::clone(&world)));
        if cache.len() > CACHED_WORLDS {
            cache.remove(0);
        }
        world
    }

    pub fn kind(&self) -> WorldKind {
        self.kind
    }

    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The drivable network.
    pub fn graph(&self) -> &RoadGraph {
        &self.graph
    }

    /// Lower-left and upper-right x/y corners of the interesting region: [x0, y0, x1, y1].
    pub fn extent_m(&self) -> [f64; 4] {
        self.extent_m
    }

    /// Number of object triangles (the terrain is implicit).
    pub fn triangle_count(&self) -> usize {
        self.objects.mesh().len()
    }

    /// The closest surface along `ray` within `max_range_m`.
    pub fn cast(&self, ray: &Ray, max_range_m: f32) -> Option<Hit> {
        let mut t_best = max_range_m;
        let mut hit = None;
        if let Some(terrain) = &self.terrain
            && let Some((t, tri)) = terrain.cast(ray, t_best)
        {
            t_best = t;
            let p = ray.at(t);
            hit = Some(Hit {
                range_m: t,
                normal: tri.normal(),
                material: Material::from_index(terrain.material_at(p.x, p.y)),
            });
        }
        if let Some(object) = self.objects.cast(ray, t_best) {
            let mesh = self.objects.mesh();
            let i = object.triangle as usize;
            hit = Some(Hit {
                range_m: object.t,
                normal: mesh.tris[i].normal(),
                material: Material::from_index(mesh.materials[i]),
            });
        }
        hit
    }

    /// Height of the first surface straight below (x, y, z_from_m), searching `depth_m` down.
    pub fn ground_below(&self, x: f64, y: f64, z_from_m: f64, depth_m: f64) -> Option<f64> {
        let ray = Ray::new(V3::from_f64(x, y, z_from_m), V3::new(0.0, 0.0, -1.0));
        self.cast(&ray, depth_m as f32)
            .map(|hit| z_from_m - f64::from(hit.range_m))
    }

    /// Distance from `p` to the nearest surface (terrain or object), up to `max_m`. Independent of the
    /// ray caster: it uses closest-point queries, so tests can check rays against it.
    pub fn distance_to_surface(&self, p: V3, max_m: f32) -> f32 {
        let terrain = self
            .terrain
            .as_ref()
            .map_or(f32::INFINITY, |t| t.distance_to_surface(p, 2));
        let objects = self
            .objects
            .nearest(p, max_m.min(terrain))
            .map_or(f32::INFINITY, |(d, _)| d);
        terrain.min(objects).min(max_m)
    }

    /// RMS slope in degrees at a `baseline_m` baseline over the terrain within `near_m` of the route
    /// graph's lanes (sampled every 2 m): `atan(sqrt(mean(|∇h|²)))`, the figure planetary surveys quote.
    /// `None` for worlds without terrain.
    pub fn rms_slope_deg(&self, near_m: f64, baseline_m: f64) -> Option<f64> {
        let terrain = self.terrain.as_ref()?;
        let (x0, y0) = terrain.origin_m();
        let size = terrain.size_m();
        let lines: Vec<Vec<[f64; 3]>> = self.graph.edges.iter().map(|(_, _, l)| l.clone()).collect();
        let cells = (size / 4.0).ceil() as usize;
        let index = lanes::LaneIndex::new(&lines, x0.min(y0), cells, 4.0, near_m);
        let half = baseline_m / 2.0;
        let (mut sum, mut count) = (0.0, 0usize);
        let steps = (size / 2.0) as usize;
        for j in 1..steps {
            for i in 1..steps {
                let (x, y) = (x0 + i as f64 * 2.0, y0 + j as f64 * 2.0);
                if index.distance_m(x, y) > near_m {
                    continue;
                }
                let gx = (terrain.height_at(x + half, y) - terrain.height_at(x - half, y)) / baseline_m;
                let gy = (terrain.height_at(x, y + half) - terrain.height_at(x, y - half)) / baseline_m;
                sum += gx * gx + gy * gy;
                count += 1;
            }
        }
        (count > 0).then(|| (sum / count as f64).sqrt().atan().to_degrees())
    }

    /// The terrain height at (x, y), for surface worlds.
    pub fn terrain_height(&self, x: f64, y: f64) -> Option<f64> {
        self.terrain.as_ref().map(|t| t.height_at(x, y))
    }
}

/// What a generator hands back.
pub(crate) struct WorldParts {
    pub terrain: Option<HeightField>,
    pub objects: crate::bvh::Mesh,
    pub graph: RoadGraph,
    pub extent_m: [f64; 4],
}
