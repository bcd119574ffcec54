//! The simulation spec (contracts.md section 2): every component kind parses to its
//! values, specs round-trip through `Spec::to_toml`, and a bank of bad specs is
//! rejected with messages that name the key, the component and the problem.

use std::path::{Path, PathBuf};

use farma::error::EXIT_BAD_INPUT;
use farma::simulator::spec::ar_is_stationary;
use farma::simulator::{
    ChannelSpec, Component, Discretization, FarmaModel, Kind, Spec, load_spec, parse_spec,
};

fn fixture(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn every_component() -> Spec {
    Spec {
        sample_rate_hz: 10.0,
        temperature_channel: Some("temp_c".into()),
        seed: Some(7),
        channels: vec![
            ChannelSpec {
                name: "gyro_x".into(),
                components: vec![
                    Component::ConstantBias { value: 0.02 },
                    Component::WhiteNoise { n: 0.005 },
                    Component::Quantization { q: 0.0001 },
                    Component::BiasInstability {
                        b: 0.003,
                        tau_min_s: Some(1.0),
                        tau_max_s: Some(1000.0),
                    },
                    Component::RateRandomWalk { k: 0.0002 },
                    Component::RateRamp { r: -1e-6 },
                    Component::GaussMarkov {
                        sigma: 0.004,
                        tau_s: 50.0,
                    },
                    Component::Sinusoid {
                        amplitude: 0.001,
                        freq_hz: 0.5,
                        phase_rad: 0.25,
                    },
                    Component::TemperatureBias {
                        coeffs: vec![0.0121, -0.0004],
                        reference_c: Some(25.0),
                    },
                    Component::ThermalRate {
                        coeff: 0.3,
                        smoothing_s: 30.0,
                        lag_s: 0.0,
                    },
                    Component::Warmup {
                        amplitude: 0.05,
                        tau_s: 600.0,
                    },
                    Component::Outliers {
                        rate_hz: 0.001,
                        scale: 0.2,
                        dof: None,
                    },
                    Component::Heteroskedastic {
                        of: Kind::WhiteNoise,
                        slope: 0.01,
                        floor: 0.0,
                        reference_c: Some(25.0),
                    },
                    Component::CrossAxis {
                        from: "gyro_y".into(),
                        gain: 0.002,
                    },
                    Component::OutputFilter {
                        order: 2,
                        bandwidth_hz: 2.0,
                        damping: Some(0.6),
                        discretization: Default::default(),
                    },
                    Component::Saturation { limit: 5.0 },
                    Component::OutputResolution {
                        quantum: 0.0001,
                        on_angle: true,
                    },
                ],
            },
            ChannelSpec {
                name: "gyro_y".into(),
                components: vec![
                    Component::Arma {
                        ar: vec![0.6, -0.2],
                        ma: vec![0.3],
                        sigma: 0.004,
                    },
                    Component::Farma(FarmaModel::Fitted {
                        model: PathBuf::from("fits/gyro_y"),
                        channel: Some("gyro_y".into()),
                    }),
                    Component::CrossAxis {
                        from: "gyro_x".into(),
                        gain: -0.001,
                    },
                ],
            },
            ChannelSpec {
                name: "gyro_z".into(),
                components: vec![
                    Component::Farma(FarmaModel::Inline {
                        p: 2,
                        q: 1,
                        d: 1,
                        f: vec![vec![0.5, 0.1, -0.02], vec![0.1]],
                        ma: vec![0.2],
                        sigma: 0.003,
                    }),
                    Component::OutputFilter {
                        order: 1,
                        bandwidth_hz: 1.0,
                        damping: None,
                        discretization: Discretization::Bilinear,
                    },
                    Component::OutputResolution {
                        quantum: 0.00001,
                        on_angle: false,
                    },
                ],
            },
        ],
    }
}

#[test]
fn every_component_fixture_parses_to_its_values() {
    let spec = load_spec(&fixture("fixtures/specs/every_component.toml")).unwrap();
    assert_eq!(spec, every_component());
    // Every kind of the contract appears.
    let kinds: std::collections::HashSet<Kind> = spec
        .channels
        .iter()
        .flat_map(|c| c.components.iter().map(Component::kind))
        .collect();
    for kind in Kind::ALL {
        assert!(kinds.contains(&kind), "{kind} missing from the fixture");
    }
}

#[test]
fn contract_example_parses() {
    let text = r#"
sample_rate_hz = 10.0
temperature_channel = "temp"   # optional
seed = 7                       # optional

[[channel]]
name = "rate"

[[channel.component]]
kind = "white_noise"
n = 0.02
"#;
    let spec = parse_spec(text, Path::new("spec.toml")).unwrap();
    assert_eq!(
        spec,
        Spec {
            sample_rate_hz: 10.0,
            temperature_channel: Some("temp".into()),
            seed: Some(7),
            channels: vec![ChannelSpec {
                name: "rate".into(),
                components: vec![Component::WhiteNoise { n: 0.02 }],
            }],
        }
    );
}

#[test]
fn optional_keys_and_integer_numbers() {
    let text = r#"
sample_rate_hz = 100
[[channel]]
name = "rate"
[[channel.component]]
kind = "bias_instability"
b = 1
[[channel.component]]
kind = "arma"
ar = []
ma = [0, 0.5]
sigma = 2
"#;
    let spec = parse_spec(text, Path::new("spec.toml")).unwrap();
    assert_eq!(spec.sample_rate_hz, 100.0);
    assert_eq!(spec.temperature_channel, None);
    assert_eq!(spec.seed, None);
    assert_eq!(
        spec.channels[0].components,
        vec![
            Component::BiasInstability {
                b: 1.0,
                tau_min_s: None,
                tau_max_s: None
            },
            Component::Arma {
                ar: vec![],
                ma: vec![0.0, 0.5],
                sigma: 2.0
            },
        ]
    );
}

#[test]
fn round_trip_every_component() {
    let spec = every_component();
    let text = spec.to_toml().unwrap();
    let back = parse_spec(&text, Path::new("written.toml")).unwrap();
    assert_eq!(back, spec, "written spec:\n{text}");
    // Writing is stable.
    assert_eq!(back.to_toml().unwrap(), text);
}

/// heteroskedastic's floor is written when above 0 and read back; a floor of 0 (the
/// default) writes no `floor` line, so specs without one round-trip unchanged.
#[test]
fn round_trip_heteroskedastic_floor() {
    let with = |floor: f64| Spec {
        sample_rate_hz: 10.0,
        temperature_channel: Some("t".into()),
        seed: None,
        channels: vec![ChannelSpec {
            name: "rate".into(),
            components: vec![
                Component::WhiteNoise { n: 0.5 },
                Component::Heteroskedastic {
                    of: Kind::WhiteNoise,
                    slope: -0.07,
                    floor,
                    reference_c: None,
                },
            ],
        }],
    };
    for floor in [0.0, 0.25, 1e-9] {
        let spec = with(floor);
        let text = spec.to_toml().unwrap();
        assert_eq!(text.contains("floor"), floor > 0.0, "{text}");
        let back = parse_spec(&text, Path::new("written.toml")).unwrap();
        assert_eq!(back, spec, "written spec:\n{text}");
        assert_eq!(back.to_toml().unwrap(), text);
    }
    let text = format!(
        "temperature_channel = \"t\"\n{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n[[channel.component]]\nkind = \"heteroskedastic\"\nof = \"white_noise\"\nslope = 0.1\n"
    );
    let spec = parse_spec(&text, Path::new("spec.toml")).unwrap();
    assert!(!spec.to_toml().unwrap().contains("floor"));
    assert!(matches!(
        spec.channels[0].components[1],
        Component::Heteroskedastic { floor: 0.0, .. }
    ));
}

#[test]
fn round_trip_the_fir_output_filter() {
    let text = format!(
        "{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n[[channel.component]]\nkind = \"output_filter\"\nform = \"fir\"\ntaps = [0.8333333333333334, 0.16666666666666669, -1e-300]\n"
    );
    let spec = parse_spec(&text, Path::new("fir.toml")).unwrap();
    assert_eq!(
        spec.channels[0].components[1],
        Component::OutputFir {
            taps: vec![0.8333333333333334, 0.16666666666666669, -1e-300]
        }
    );
    let written = spec.to_toml().unwrap();
    assert!(written.contains("form = \"fir\""), "{written}");
    let back = parse_spec(&written, Path::new("written.toml")).unwrap();
    assert_eq!(back, spec, "written spec:\n{written}");
    assert_eq!(back.to_toml().unwrap(), written);
    // the low-pass form named explicitly is the default form
    let lp = parse_spec(
        &behind_noise(
            "kind = \"output_filter\"\nform = \"lowpass\"\norder = 1\nbandwidth_hz = 2.0",
        ),
        Path::new("lp.toml"),
    )
    .unwrap();
    assert!(matches!(
        lp.channels[0].components[1],
        Component::OutputFilter { order: 1, .. }
    ));
}

#[test]
fn round_trip_awkward_values() {
    // Values whose decimal form is long, tiny, huge or negative zero, names that need
    // quoting, and no optional keys.
    let spec = Spec {
        sample_rate_hz: 1.0 / 3.0,
        temperature_channel: Some("temp \"C\"\\ä".into()),
        seed: Some(i64::MAX as u64),
        channels: vec![
            ChannelSpec {
                name: "x axis\t\"1\"".into(),
                components: vec![
                    Component::WhiteNoise { n: 0.1 + 0.2 },
                    Component::ConstantBias { value: -0.0 },
                    Component::RateRamp {
                        r: -1.234_567_890_123_456_7e-300,
                    },
                    Component::RateRandomWalk { k: 1e300 },
                    Component::CrossAxis {
                        from: "y".into(),
                        gain: f64::MIN_POSITIVE,
                    },
                ],
            },
            ChannelSpec {
                name: "y".into(),
                components: vec![Component::Farma(FarmaModel::Fitted {
                    model: PathBuf::from("dir with space/fit's"),
                    channel: None,
                })],
            },
        ],
    };
    let text = spec.to_toml().unwrap();
    let back = parse_spec(&text, Path::new("written.toml")).unwrap();
    assert_eq!(back, spec, "written spec:\n{text}");
    // -0.0 == 0.0 in PartialEq: check the sign survived too.
    match back.channels[0].components[1] {
        Component::ConstantBias { value } => assert!(value.is_sign_negative()),
        ref other => panic!("{other:?}"),
    }
}

#[test]
fn to_toml_refuses_an_invalid_spec_as_an_internal_error() {
    let mut spec = every_component();
    spec.channels[0].components[1] = Component::WhiteNoise { n: -1.0 };
    let err = spec.to_toml().unwrap_err();
    assert_eq!(err.exit_code(), 1, "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains("channel 'gyro_x' component 2 (white_noise): 'n' must be >= 0"),
        "{msg}"
    );
    // And a non-finite value.
    let mut spec = every_component();
    spec.sample_rate_hz = f64::NAN;
    assert!(
        spec.to_toml()
            .unwrap_err()
            .to_string()
            .contains("sample_rate_hz")
    );
}

#[test]
fn missing_file_is_bad_input() {
    let err = load_spec(&fixture("fixtures/specs/no_such_spec.toml")).unwrap_err();
    assert_eq!(err.exit_code(), EXIT_BAD_INPUT);
    assert!(err.to_string().contains("no_such_spec.toml"), "{err}");
}

#[test]
fn ar_stationarity_boundary() {
    assert!(ar_is_stationary(&[0.999]));
    assert!(!ar_is_stationary(&[1.0]));
    assert!(!ar_is_stationary(&[0.5, 0.5])); // unit root: 1 - 0.5 z - 0.5 z^2 at z = 1
}

#[test]
fn outliers_with_dof_round_trip_and_a_dof_below_one_is_refused() {
    let text = component("kind = \"outliers\"\nrate_hz = 0.01\nscale = 0.3\ndof = 2.5");
    let spec = parse_spec(&text, Path::new("spec.toml")).unwrap();
    assert_eq!(
        spec.channels[0].components[0],
        Component::Outliers {
            rate_hz: 0.01,
            scale: 0.3,
            dof: Some(2.5),
        }
    );
    let again = parse_spec(&spec.to_toml().unwrap(), Path::new("again.toml")).unwrap();
    assert_eq!(again, spec);
    let msg = reject(&component(
        "kind = \"outliers\"\nrate_hz = 0.01\nscale = 0.3\ndof = 0.5",
    ));
    assert_has(&msg, &["component 1 (outliers)", "'dof'", ">= 1"]);
}

/// A valid one-channel header the bad specs below extend.
const HEAD: &str = "sample_rate_hz = 10.0\n[[channel]]\nname = \"rate\"\n";

/// Parses `text` as `spec.toml` and returns the error message, checking exit code 2.
fn reject(text: &str) -> String {
    match parse_spec(text, Path::new("spec.toml")) {
        Ok(spec) => panic!("accepted a bad spec:\n{text}\nas {spec:?}"),
        Err(e) => {
            assert_eq!(e.exit_code(), EXIT_BAD_INPUT, "{e}");
            e.to_string()
        }
    }
}

/// One component appended to HEAD.
fn component(body: &str) -> String {
    format!("{HEAD}[[channel.component]]\n{body}\n")
}

/// One component appended to HEAD after a white noise (an output-path stage needs a
/// component to act on).
fn behind_noise(body: &str) -> String {
    format!(
        "{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n[[channel.component]]\n{body}\n"
    )
}

fn assert_has(msg: &str, parts: &[&str]) {
    for part in parts {
        assert!(msg.contains(part), "message {msg:?} lacks {part:?}");
    }
}

#[test]
fn bad_specs_name_the_key_and_the_problem() {
    // (spec text, parts the message must contain)
    let cases: Vec<(String, Vec<&str>)> = vec![
        // Unknown and missing keys.
        (
            component("kind = \"white_noise\"\nnn = 0.1"),
            vec![
                "spec.toml: unknown key 'nn' in channel 'rate' component 1 (white_noise)",
                "did you mean 'n'",
            ],
        ),
        (
            format!("{HEAD}[[channel.component]]\nkind = \"constant_bias\"\nvalue = 1\n[[channel.component]]\nkind = \"white_noise\"\n"),
            vec!["spec.toml: channel 'rate' component 2 (white_noise): missing parameter 'n'"],
        ),
        (
            format!("sample_rte_hz = 10.0\n{HEAD}"),
            vec!["unknown key 'sample_rte_hz' at the top level", "did you mean 'sample_rate_hz'"],
        ),
        (
            "[[channel]]\nname = \"rate\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 1\n".into(),
            vec!["the top level: missing key 'sample_rate_hz'"],
        ),
        (
            "sample_rate_hz = 10.0\n".into(),
            vec!["missing key 'channel'"],
        ),
        (
            format!("{HEAD}gain = 2\n[[channel.component]]\nkind = \"white_noise\"\nn = 1\n"),
            vec!["unknown key 'gain' in channel 'rate'"],
        ),
        (
            "sample_rate_hz = 10.0\n[[channel]]\n[[channel.component]]\nkind = \"white_noise\"\nn = 1\n".into(),
            vec!["channel 1: missing key 'name'"],
        ),
        (
            component("n = 0.1"),
            vec!["channel 'rate' component 1: missing key 'kind'"],
        ),
        (
            component("kind = \"white_nosie\"\nn = 0.1"),
            vec!["channel 'rate' component 1: unknown kind 'white_nosie'", "did you mean 'white_noise'"],
        ),
        (
            component("kind = \"sinusoid\"\namplitude = 1.0\nfreq_hz = 1.0"),
            vec!["component 1 (sinusoid): missing parameter 'phase_rad'"],
        ),
        (
            component("kind = \"gauss_markov\"\nsigma = 1.0"),
            vec!["component 1 (gauss_markov): missing parameter 'tau_s'"],
        ),
        // Wrong types.
        (
            component("kind = \"white_noise\"\nn = \"0.1\""),
            vec!["component 1 (white_noise): 'n' must be a number, found a string"],
        ),
        (
            component("kind = \"arma\"\nar = 0.5\nma = []\nsigma = 1"),
            vec!["component 1 (arma): 'ar' must be an array of numbers"],
        ),
        (
            format!("{HEAD}component = 3\n"),
            vec!["channel 'rate': 'component' must be an array of tables ([[channel.component]])"],
        ),
        (
            "sample_rate_hz = 10.0\n[channel]\nname = \"rate\"\n".into(),
            vec!["'channel' must be an array of tables ([[channel]])"],
        ),
        (
            format!("seed = -1\n{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n"),
            vec!["the top level: 'seed' must be an integer >= 0"],
        ),
        (
            format!("seed = 1.5\n{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n"),
            vec!["'seed' must be an integer >= 0, found a float"],
        ),
        // Negative sizes, bad times.
        (
            component("kind = \"white_noise\"\nn = -0.1"),
            vec!["channel 'rate' component 1 (white_noise): 'n' must be >= 0, found -0.1"],
        ),
        (
            component("kind = \"quantization\"\nq = -1"),
            vec!["(quantization): 'q' must be >= 0"],
        ),
        (
            component("kind = \"bias_instability\"\nb = -1"),
            vec!["(bias_instability): 'b' must be >= 0"],
        ),
        (
            component("kind = \"bias_instability\"\nb = 1\ntau_min_s = 100.0\ntau_max_s = 10.0"),
            vec!["(bias_instability): 'tau_min_s' (100) must be below 'tau_max_s' (10)"],
        ),
        (
            component("kind = \"bias_instability\"\nb = 1\ntau_min_s = 0.0"),
            vec!["(bias_instability): 'tau_min_s' must be > 0"],
        ),
        (
            component("kind = \"rate_random_walk\"\nk = -1e-3"),
            vec!["(rate_random_walk): 'k' must be >= 0"],
        ),
        (
            component("kind = \"gauss_markov\"\nsigma = -1.0\ntau_s = 1.0"),
            vec!["(gauss_markov): 'sigma' must be >= 0"],
        ),
        (
            component("kind = \"gauss_markov\"\nsigma = 1.0\ntau_s = 0.0"),
            vec!["(gauss_markov): 'tau_s' must be > 0, found 0"],
        ),
        (
            component("kind = \"warmup\"\namplitude = -1.0\ntau_s = -5.0"),
            vec!["(warmup): 'tau_s' must be > 0, found -5"],
        ),
        (
            component("kind = \"sinusoid\"\namplitude = -1.0\nfreq_hz = 1.0\nphase_rad = 0.0"),
            vec!["(sinusoid): 'amplitude' must be >= 0", "phase_rad"],
        ),
        (
            component("kind = \"sinusoid\"\namplitude = 1.0\nfreq_hz = -1.0\nphase_rad = 0.0"),
            vec!["(sinusoid): 'freq_hz' must be >= 0"],
        ),
        (
            component("kind = \"sinusoid\"\namplitude = 1.0\nfreq_hz = 5.0\nphase_rad = 0.0"),
            vec!["(sinusoid): 'freq_hz' = 5 must be below the Nyquist frequency 5 Hz"],
        ),
        (
            component("kind = \"outliers\"\nrate_hz = 20.0\nscale = 1.0"),
            vec!["(outliers): 'rate_hz' = 20 exceeds sample_rate_hz = 10"],
        ),
        (
            component("kind = \"outliers\"\nrate_hz = 1.0\nscale = -1.0"),
            vec!["(outliers): 'scale' must be >= 0"],
        ),
        (
            format!("temperature_channel = \"t\"\n{HEAD}[[channel.component]]\nkind = \"thermal_rate\"\ncoeff = 1.0\nsmoothing_s = -1.0\n"),
            vec!["(thermal_rate): 'smoothing_s' must be >= 0"],
        ),
        (
            component("kind = \"constant_bias\"\nvalue = nan"),
            vec!["(constant_bias): 'value' must be finite, found NaN"],
        ),
        (
            component("kind = \"white_noise\"\nn = inf"),
            vec!["(white_noise): 'n' must be finite"],
        ),
        (
            "sample_rate_hz = 0.0\n[[channel]]\nname = \"rate\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 1\n".to_string(),
            vec!["'sample_rate_hz' must be > 0"],
        ),
        // ARMA and FARMA.
        (
            component("kind = \"arma\"\nar = [1.2]\nma = []\nsigma = 1"),
            vec!["(arma): 'ar' = [1.2] is not stationary"],
        ),
        (
            component("kind = \"arma\"\nar = [0.5]\nma = []\nsigma = -1"),
            vec!["(arma): 'sigma' must be >= 0"],
        ),
        (
            component("kind = \"arma\"\nar = [0.5]\nsigma = 1"),
            vec!["(arma): missing parameter 'ma'"],
        ),
        (
            component("kind = \"farma\"\nmodel = \"fits\"\nsigma = 1.0"),
            vec!["(farma): give either 'model'", "not both", "'sigma'"],
        ),
        (
            component("kind = \"farma\""),
            vec!["(farma): missing parameter 'model'"],
        ),
        (
            component("kind = \"farma\"\np = 1\nq = 0\nd = 1\nma = []\nsigma = 1"),
            vec!["(farma): missing parameter 'f'"],
        ),
        (
            component("kind = \"farma\"\np = 2\nq = 0\nd = 1\nf = [[0.5]]\nma = []\nsigma = 1"),
            vec!["(farma): 'f' has 1 polynomial(s) but p = 2"],
        ),
        (
            component("kind = \"farma\"\np = 1\nq = 1\nd = 1\nf = [[0.5]]\nma = []\nsigma = 1"),
            vec!["(farma): 'ma' has 0 coefficient(s) but q = 1"],
        ),
        (
            component("kind = \"farma\"\np = 1\nq = 0\nd = 0\nf = [[0.5]]\nma = []\nsigma = 1"),
            vec!["(farma): 'd' must be >= 1"],
        ),
        (
            component("kind = \"farma\"\np = 1\nq = 0\nd = 1\nf = [[]]\nma = []\nsigma = 1"),
            vec!["(farma): 'f' entry 1 (f_1) has no coefficients"],
        ),
        (
            component("kind = \"farma\"\np = -1\nq = 0\nd = 1\nf = []\nma = []\nsigma = 1"),
            vec!["(farma): 'p' must be an integer >= 0"],
        ),
        (
            component("kind = \"farma\"\np = 1\nq = 0\nd = 1\nf = [0.5]\nma = []\nsigma = 1"),
            vec!["(farma): 'f' must be an array of arrays of numbers"],
        ),
        (
            component("kind = \"farma\"\np = 1\nq = 0\nd = 1\nf = [[0.5]]\nma = []\nsigma = 1\nchannel = \"x\""),
            vec!["(farma): 'channel' names a channel of a fitted model and needs 'model'"],
        ),
        // Cross-references.
        (
            format!("{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n[[channel]]\nname = \"rate\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 1\n"),
            vec!["channel 'rate' appears twice"],
        ),
        (
            component("kind = \"cross_axis\"\nfrom = \"gyro_q\"\ngain = 0.1"),
            vec!["(cross_axis): 'from' = 'gyro_q' is not a channel of the spec"],
        ),
        (
            component("kind = \"cross_axis\"\nfrom = \"rate\"\ngain = 0.1"),
            vec!["(cross_axis): 'from' = 'rate' is this channel"],
        ),
        (
            format!("{HEAD}[[channel.component]]\nkind = \"cross_axis\"\nfrom = \"b\"\ngain = 0.1\n[[channel.component]]\nkind = \"cross_axis\"\nfrom = \"b\"\ngain = 0.2\n[[channel]]\nname = \"b\"\n[[channel.component]]\nkind = \"white_noise\"\nn = 1\n"),
            vec!["component 2 (cross_axis): a second cross_axis from 'b'"],
        ),
        (
            format!("temperature_channel = \"t\"\n{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n[[channel.component]]\nkind = \"heteroskedastic\"\nof = \"gauss_markov\"\nslope = 0.1\n"),
            vec!["component 2 (heteroskedastic): 'of' = 'gauss_markov' but channel 'rate' has no gauss_markov component"],
        ),
        (
            format!("temperature_channel = \"t\"\n{HEAD}[[channel.component]]\nkind = \"sinusoid\"\namplitude = 1\nfreq_hz = 1\nphase_rad = 0\n[[channel.component]]\nkind = \"heteroskedastic\"\nof = \"sinusoid\"\nslope = 0.1\n"),
            vec!["(heteroskedastic): 'of' = 'sinusoid' is not a noise kind"],
        ),
        (
            format!("temperature_channel = \"t\"\n{HEAD}[[channel.component]]\nkind = \"heteroskedastic\"\nof = \"pink\"\nslope = 0.1\n"),
            vec!["(heteroskedastic): 'of' = 'pink' is not a component kind"],
        ),
        (
            format!("temperature_channel = \"t\"\n{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n[[channel.component]]\nkind = \"heteroskedastic\"\nof = \"white_noise\"\nslope = 0.1\n[[channel.component]]\nkind = \"heteroskedastic\"\nof = \"white_noise\"\nslope = 0.2\n"),
            vec!["component 3 (heteroskedastic): a second heteroskedastic component for 'white_noise'"],
        ),
        (
            format!("temperature_channel = \"t\"\n{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n[[channel.component]]\nkind = \"heteroskedastic\"\nof = \"white_noise\"\nslope = 0.1\nfloor = -0.1\n"),
            vec!["component 2 (heteroskedastic): 'floor' must be >= 0, found -0.1"],
        ),
        (
            format!("temperature_channel = \"t\"\n{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n[[channel.component]]\nkind = \"heteroskedastic\"\nof = \"white_noise\"\nslope = 0.1\nfloor = 1\n"),
            vec!["component 2 (heteroskedastic): 'floor' must be < 1", "found 1"],
        ),
        (
            component("kind = \"temperature_bias\"\ncoeffs = [0.1]"),
            vec!["component 1 (temperature_bias): needs a temperature", "temperature_channel"],
        ),
        (
            format!("temperature_channel = \"t\"\n{HEAD}[[channel.component]]\nkind = \"temperature_bias\"\ncoeffs = []\n"),
            vec!["(temperature_bias): 'coeffs' must hold at least one coefficient"],
        ),
        (
            format!("temperature_channel = \"rate\"\n{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n"),
            vec!["'temperature_channel' = 'rate' is also a simulated channel"],
        ),
        (
            HEAD.to_string(),
            vec!["channel 'rate' has no components"],
        ),
        // The output path.
        (
            behind_noise("kind = \"output_filter\"\norder = 3\nbandwidth_hz = 1.0"),
            vec!["(output_filter): 'order' must be 1 or 2, found an integer (3)"],
        ),
        (
            behind_noise("kind = \"output_filter\"\norder = 1\nbandwidth_hz = 0.0"),
            vec!["(output_filter): 'bandwidth_hz' must be > 0, found 0"],
        ),
        (
            behind_noise("kind = \"output_filter\"\norder = 2\nbandwidth_hz = inf"),
            vec!["(output_filter): 'bandwidth_hz' must be finite"],
        ),
        (
            behind_noise("kind = \"output_filter\"\norder = 1\nbandwidth_hz = 1.0\ndamping = 0.7"),
            vec!["(output_filter): 'damping' is a parameter of a second-order filter"],
        ),
        (
            behind_noise("kind = \"output_filter\"\norder = 2\nbandwidth_hz = 1.0\ndamping = -0.7"),
            vec!["(output_filter): 'damping' must be > 0, found -0.7"],
        ),
        (
            behind_noise("kind = \"output_filter\"\norder = 2\nbandwidth_hz = 1.0\ndamping = 1e9"),
            vec!["(output_filter): 'damping' = 1e9 is out of range"],
        ),
        (
            behind_noise("kind = \"output_filter\"\nbandwidth_hz = 1.0"),
            vec!["(output_filter): missing parameter 'order'"],
        ),
        (
            behind_noise(
                "kind = \"output_filter\"\norder = 1\nbandwidth_hz = 1.0\ndiscretization = \"tustin\"",
            ),
            vec!["'discretization'", "\"zoh\" or \"bilinear\""],
        ),
        (
            behind_noise(
                "kind = \"output_filter\"\norder = 1\nbandwidth_hz = 60.0\ndiscretization = \"bilinear\"",
            ),
            vec!["'bandwidth_hz' = 60 must be below the Nyquist frequency"],
        ),
        (
            behind_noise("kind = \"output_filter\"\nform = \"fir\"\ntaps = []"),
            vec!["(output_filter): 'taps' must hold 1 to 64 numbers, found 0"],
        ),
        (
            behind_noise(&format!(
                "kind = \"output_filter\"\nform = \"fir\"\ntaps = [{}]",
                vec!["0.1"; 65].join(", ")
            )),
            vec!["(output_filter): 'taps' must hold 1 to 64 numbers, found 65"],
        ),
        (
            behind_noise("kind = \"output_filter\"\nform = \"fir\"\ntaps = [0.5, nan]"),
            vec!["(output_filter): 'taps' must hold finite numbers, found NaN"],
        ),
        (
            behind_noise("kind = \"output_filter\"\nform = \"fir\"\ntaps = [0.5, \"a\"]"),
            vec!["(output_filter): 'taps' must be an array of numbers"],
        ),
        (
            behind_noise("kind = \"output_filter\"\nform = \"fir\""),
            vec!["(output_filter): missing parameter 'taps'"],
        ),
        (
            behind_noise("kind = \"output_filter\"\nform = \"fir\"\ntaps = [1.0]\norder = 1"),
            vec!["(output_filter): 'order' belongs to the low-pass form"],
        ),
        (
            behind_noise("kind = \"output_filter\"\norder = 1\nbandwidth_hz = 1.0\ntaps = [1.0]"),
            vec!["(output_filter): 'taps' belongs to form = \"fir\""],
        ),
        (
            behind_noise("kind = \"output_filter\"\nform = \"iir\"\ntaps = [1.0]"),
            vec!["(output_filter): 'form' must be \"lowpass\" or \"fir\""],
        ),
        (
            behind_noise("kind = \"saturation\"\nlimit = -3"),
            vec!["(saturation): 'limit' must be > 0, found -3"],
        ),
        (
            behind_noise("kind = \"saturation\"\nlimit = nan"),
            vec!["(saturation): 'limit' must be finite"],
        ),
        (
            behind_noise("kind = \"output_resolution\"\nquantum = 0"),
            vec!["(output_resolution): 'quantum' must be > 0, found 0"],
        ),
        (
            behind_noise("kind = \"output_resolution\"\nquantum = 0.05\non_angle = 1"),
            vec!["(output_resolution): 'on_angle' must be a boolean (true or false), found an integer (1)"],
        ),
        (
            component("kind = \"output_resolution\"\nquantum = 0.05"),
            vec!["channel 'rate' has only output-path components"],
        ),
        (
            format!("{HEAD}[[channel.component]]\nkind = \"white_noise\"\nn = 1\n[[channel.component]]\nkind = \"saturation\"\nlimit = 1\n[[channel.component]]\nkind = \"saturation\"\nlimit = 2\n"),
            vec!["component 3 (saturation): a second saturation in channel 'rate'"],
        ),
    ];
    for (text, parts) in &cases {
        let msg = reject(text);
        assert_has(&msg, parts);
        assert!(msg.starts_with("spec.toml"), "{msg}");
    }
}

#[test]
fn toml_syntax_errors_give_line_and_column() {
    let text = "sample_rate_hz = 10.0\n[[channel]]\nname = \"rate\n";
    let msg = reject(text);
    assert!(msg.starts_with("spec.toml:3: column "), "{msg}");
    assert!(msg.contains("invalid TOML"), "{msg}");
    assert!(!msg.contains('\n'), "one line: {msg}");

    // A duplicate key is a TOML error too, at the second occurrence.
    let text = "sample_rate_hz = 10.0\nsample_rate_hz = 20.0\n";
    let msg = reject(text);
    assert!(msg.starts_with("spec.toml:2: column 1:"), "{msg}");
}

#[test]
fn bad_fixture_files_are_rejected_with_their_path() {
    let dir = fixture("fixtures/specs/bad");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        // The first line says what the message must contain: "# expect: ...".
        let expect = text
            .lines()
            .next()
            .and_then(|l| l.strip_prefix("# expect: "))
            .unwrap_or_else(|| panic!("{} lacks '# expect: ' on line 1", path.display()));
        let err = load_spec(&path).unwrap_err();
        assert_eq!(err.exit_code(), EXIT_BAD_INPUT);
        let msg = err.to_string();
        assert!(msg.contains(&*path.to_string_lossy()), "{msg}");
        assert!(
            msg.contains(expect),
            "{}: {msg:?} lacks {expect:?}",
            path.display()
        );
        n += 1;
    }
    assert!(n >= 3, "only {n} bad spec fixtures");
}

#[test]
fn round_trip_is_bit_exact_for_random_finite_values() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(952);
    let mut values = Vec::new();
    while values.len() < 2000 {
        // Random bit patterns cover subnormals, huge and tiny exponents, both signs.
        let x = f64::from_bits(rng.random::<u64>());
        if x.is_finite() {
            values.push(x);
        }
    }
    let spec = Spec {
        sample_rate_hz: 100.0,
        temperature_channel: Some("t".into()),
        seed: Some(rng.random_range(0..=i64::MAX as u64)),
        channels: vec![ChannelSpec {
            name: "rate".into(),
            components: vec![
                Component::TemperatureBias {
                    coeffs: values.clone(),
                    reference_c: Some(values[0]),
                },
                Component::ConstantBias { value: values[1] },
            ],
        }],
    };
    let back = parse_spec(&spec.to_toml().unwrap(), Path::new("written.toml")).unwrap();
    assert_eq!(back.seed, spec.seed);
    match &back.channels[0].components[0] {
        Component::TemperatureBias { coeffs, .. } => {
            assert_eq!(coeffs.len(), values.len());
            for (a, b) in coeffs.iter().zip(&values) {
                assert_eq!(a.to_bits(), b.to_bits(), "{a:e} vs {b:e}");
            }
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn to_toml_refuses_a_seed_toml_cannot_hold() {
    let mut spec = every_component();
    spec.seed = Some(u64::MAX);
    let msg = spec.to_toml().unwrap_err().to_string();
    assert!(msg.contains("'seed' must be at most"), "{msg}");
}
