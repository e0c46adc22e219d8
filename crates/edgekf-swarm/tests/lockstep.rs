//! The world and the agents over real Zenoh sessions (threads of one process here; the CLI's
//! `edgekf swarm` runs them as processes): in lockstep without loss the world's results equal
//! the engine's run 0 bit for bit, and every link delivered every message.

use std::net::{TcpListener, UdpSocket};
use std::time::Duration;

use edgekf::scenario::Scenario;
use edgekf::sim::{self, Quiet};
use edgekf_swarm::agent_node::{run_agent, AgentOptions};
use edgekf_swarm::world_node::{run_world, WorldOptions};
use edgekf_swarm::{Endpoints, Mode};

fn endpoints(n: usize, tag: &str) -> Endpoints {
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let base = (21_000..60_000)
        .step_by(97)
        .find(|&b| (0..n).all(|i| UdpSocket::bind(("127.0.0.1", (b + i) as u16)).is_ok()))
        .unwrap() as u16;
    Endpoints {
        swarm: format!("test-{tag}-{}", std::process::id()),
        world: format!("tcp/127.0.0.1:{port}"),
        mesh_base_port: base,
        ..Endpoints::default()
    }
}

fn scenario(estimators: &str, extra: &str) -> Scenario {
    let text = format!(
        "name = \"swarm-test\"\nestimators = [{estimators}]\n[framework]\npreset = \"hexagon\"\n\
         [sim]\nsteps = 120\nruns = 1\nevery = 10\n[noise]\nsigma_v = 0.1\nsigma_w = 0.001\n{extra}"
    );
    let spec = edgekf_io::spec_from_toml(&text).expect("TOML");
    Scenario::from_spec(&spec, None).expect("valid")
}

fn swarm(sc: &Scenario, tag: &str) -> edgekf_swarm::world_node::WorldOutcome {
    let n = sc.framework().agents();
    let ep = endpoints(n, tag);
    let timeout = Duration::from_secs(30);
    std::thread::scope(|s| {
        let agents: Vec<_> = (0..n)
            .map(|id| {
                let o = AgentOptions {
                    id,
                    endpoints: ep.clone(),
                    mode: Mode::Lockstep,
                    lossy: false,
                    live: false,
                    grace: Duration::from_millis(2),
                    timeout,
                };
                let sc = sc.clone();
                s.spawn(move || run_agent(&sc, &o))
            })
            .collect();
        let o = WorldOptions {
            endpoints: ep.clone(),
            mode: Mode::Lockstep,
            live: false,
            timeout,
            after_ready: None,
            drawn_failures: true,
            frames: Default::default(),
        };
        let out = run_world(sc, &o, &mut |_| {}).expect("world");
        for a in agents {
            a.join().expect("agent thread").expect("agent");
        }
        out
    })
}

#[test]
fn lockstep_over_zenoh_equals_the_engine() {
    for (tag, est) in [
        (
            "rkf",
            r#""rkf", "mle", { kind = "mmse", prior_var = 1e-3 }, "jrkf""#,
        ),
        ("garkf", r#""garkf""#),
    ] {
        let sc = scenario(est, "");
        let engine = sim::run(&sc, &Quiet).expect("engine");
        let out = swarm(&sc, tag);
        assert_eq!(engine, out.results, "{tag}");
        let inputs = out.network.total("input");
        assert_eq!(inputs.lost, 0, "{tag}: {inputs:?}");
        assert_eq!(inputs.sent, inputs.received, "{tag}");
        // 10 agents, 60 directed edges: each edge's input of every step (those of the last
        // step, which no step takes, may still be on their way when the world stops).
        let steps = sc.steps() as u64;
        assert!(
            (60 * (steps - 1)..=60 * steps).contains(&inputs.received),
            "{tag}: {inputs:?}"
        );
        if tag == "garkf" {
            let ex = out.network.total("exchange");
            assert_eq!(ex.received, 60 * sc.steps() as u64);
        }
    }
}
