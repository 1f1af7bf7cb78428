//! The `sim` source passes the generic source conformance suite for every world, and two robots of one
//! fleet built through the registry share the world's frame but drive different routes.

use skid_core::{Params, PluginContext, Registry, RobotId};

fn registry() -> Registry {
    let mut registry = Registry::new();
    if let Err(error) = skid_source_sim::register(&mut registry) {
        panic!("the sim source does not register: {error}");
    }
    registry
}

#[test]
fn sim_source_conforms_in_every_world() {
    let registry = registry();
    for world in ["planetary", "cave", "urban"] {
        let params = Params::from_toml_str(&format!("world = \"{world}\"\nsensor = \"vlp16\"\nframes = 3"))
            .expect("valid TOML");
        let mut source = registry
            .source
            .create("sim", &params, &PluginContext::default())
            .expect("sim source");
        assert_eq!(
            skid_testkit::source::check_source(source.as_mut(), 10),
            3,
            "{world}"
        );
    }
}

#[test]
fn robots_of_a_fleet_start_in_different_places() {
    let registry = registry();
    let params =
        Params::from_toml_str("world = \"urban\"\nsensor = \"avia\"\nframes = 1").expect("valid TOML");
    let start = |robot: u32| {
        let context = PluginContext {
            robot: RobotId(robot),
            fleet_size: 2,
            ..PluginContext::default()
        };
        let mut source = registry
            .source
            .create("sim", &params, &context)
            .expect("sim source");
        let scan = source.next_scan().expect("reads").expect("one scan");
        scan.ground_truth_world_from_sensor
            .expect("ground truth")
            .translation
            .vector
    };
    assert!((start(0) - start(1)).norm() > 50.0);
}
