//! Every partial derivative against central finite differences at >= 100 random states per
//! check, away from the kinks (gates at n^T s = 0, FOV edges, albedo cell gates, roll-off
//! ends, the saturation clip), which states are rejected for explicitly. Run with
//! `--nocapture` to see the observed maximum errors.

use crate::common;

use common::*;
use nalgebra::Vector3;
use pdcal_attitude::normal_from_az_el;
use pdcal_photodiode::*;

/// Scalar partials of a term w.r.t. its own parameters, by central differences.
fn check_term_parameters(term: &mut dyn Term, state: &State, stats: &mut Stats, label: &str) {
    let scene = state.scene();
    let mut d = vec![0.0; term.parameters().len()];
    term.partials(&state.pd, 0, &scene, &mut d);
    for (k, &analytic) in d.iter().enumerate() {
        let p0 = term.parameters()[k].value;
        let h = H * p0.abs().max(1.0);
        let mut at = |p: f64| {
            term.parameters_mut()[k].value = p;
            term.value(&state.pd, 0, &scene)
        };
        let fd = (at(p0 + h) - at(p0 - h)) / (2.0 * h);
        at(p0);
        stats.check(&format!("{label} d/dp[{k}]"), analytic, fd);
    }
}

fn check_term(term: &mut dyn Term, state: &State, stats: &mut Stats, label: &str) {
    let mut d = vec![0.0; term.parameters().len()];
    let sens = term.partials(&state.pd, 0, &state.scene(), &mut d);
    let value = |s: &State| term.value(&s.pd, 0, &s.scene());
    check_sensitivity(state, &sens, &value, stats, label);
    check_term_parameters(term, state, stats, label);
}

fn lit(s: &State) -> bool {
    s.away_from_kinks() && s.pd.accepts(s.cos_sun())
}

#[test]
fn direct_sun_hard_partials_match_finite_differences() {
    let mut stats = Stats::default();
    let mut term = DirectSun::default();
    for_states(1, STATES, lit, |s| {
        let s = State {
            sun_fraction: 1.0,
            ..s.clone()
        };
        check_term(&mut term, &s, &mut stats, "sun");
    });
    stats.report("sun (hard)");
    assert!(stats.checked >= 7 * STATES / 2);
}

/// `C` is the output at 1 AU: every term built on the direct Sun, and each of its partials,
/// is the 1-AU one times `(1 AU / r_sun)^2` (the factor enters only as a scale).
#[test]
fn direct_sun_terms_scale_with_the_inverse_square_of_the_sun_distance() {
    let mut checked = 0;
    for_states(2, STATES, lit, |s| {
        let at_1au = State {
            sun_distance_factor: 1.0,
            ..s.clone()
        };
        let f = s.sun_distance_factor;
        let terms: [Box<dyn Term>; 4] = [
            Box::new(DirectSun::default()),
            Box::new(DirectSun {
                shadow: ShadowMode::Penumbra,
            }),
            Box::new(Penumbra),
            Box::new(TimeOffset::new(0.2)),
        ];
        for term in &terms {
            let a = term.partials(&s.pd, 0, &s.scene(), &mut [0.0; 1]);
            let b = term.partials(&at_1au.pd, 0, &at_1au.scene(), &mut [0.0; 1]);
            let close = |x: f64, y: f64| (x - f * y).abs() <= 1e-14 * (1.0 + y.abs());
            assert!(close(a.value_v, b.value_v), "{:?}", term.id());
            assert!(close(a.d_scale, b.d_scale), "{:?}", term.id());
            for k in 0..3 {
                assert!(close(a.d_attitude[k], b.d_attitude[k]), "{:?}", term.id());
                assert!(close(a.d_normal[k], b.d_normal[k]), "{:?}", term.id());
            }
            checked += 1;
        }
    });
    assert!(checked >= STATES);
}

#[test]
fn direct_sun_penumbra_partials_match_finite_differences() {
    let mut stats = Stats::default();
    let mut term = DirectSun {
        shadow: ShadowMode::Penumbra,
    };
    for_states(
        2,
        STATES,
        |s| lit(s) && s.sun_fraction > 0.05,
        |s| {
            check_term(&mut term, s, &mut stats, "sun penumbra");
        },
    );
    stats.report("sun (penumbra)");
}

#[test]
fn penumbra_term_partials_match_finite_differences() {
    let mut stats = Stats::default();
    for_states(
        3,
        STATES,
        |s| lit(s) && (s.sun_fraction - 0.5).abs() > 0.05,
        |s| {
            check_term(&mut Penumbra, s, &mut stats, "penumbra");
        },
    );
    stats.report("penumbra");
}

#[test]
fn albedo_included_partials_match_finite_differences() {
    let mut stats = Stats::default();
    let mut term = Albedo {
        partials: AlbedoPartials::Included,
    };
    for_states(4, STATES, State::away_from_kinks, |s| {
        check_term(&mut term, s, &mut stats, "albedo included");
    });
    stats.report("albedo (included)");
    assert!(
        stats.checked > STATES,
        "albedo states should mostly see some cells"
    );
}

#[test]
fn albedo_neglected_has_scale_partial_only() {
    let mut stats = Stats::default();
    let term = Albedo::default();
    for_states(5, STATES, State::away_from_kinks, |s| {
        let scene = s.scene();
        let sens = term.partials(&s.pd, 0, &scene, &mut []);
        let full = Albedo {
            partials: AlbedoPartials::Included,
        }
        .partials(&s.pd, 0, &scene, &mut []);
        assert_eq!(sens.d_attitude, Vector3::zeros());
        assert_eq!(sens.d_normal, Vector3::zeros());
        assert_eq!(sens.value_v, full.value_v);
        let fd = central(
            |h| {
                let mut t = s.clone();
                t.pd.scale_v += h;
                term.value(&t.pd, 0, &t.scene())
            },
            H,
        );
        stats.check("albedo neglected d/dC", sens.d_scale, fd);
    });
    stats.report("albedo (neglected) d/dC");
}

#[test]
fn fov_rolloff_partials_match_finite_differences() {
    let mut stats = Stats::default();
    let mut rng = rng(6);
    for_states(
        7,
        STATES,
        |s| lit(s) && s.sun_fraction > 0.5,
        |s| {
            use rand::RngExt;
            // Draw the taper so that the state's incidence falls inside it or beyond the cutoff
            // about equally, keeping 0.01 rad from both ends (the second derivative jumps there).
            let theta = s.cos_sun().acos();
            let start = (theta - rng.random_range(0.02..0.6)).max(0.01);
            let cutoff = if rng.random_bool(0.7) {
                (theta + rng.random_range(0.02..0.6)).min(std::f64::consts::FRAC_PI_2)
            } else {
                theta - 0.01 * rng.random_range(1.0..2.0)
            };
            let Ok(mut term) = FovRolloff::new(start, cutoff) else {
                return;
            };
            if (theta - start).abs() < 0.01 || (theta - cutoff).abs() < 0.01 {
                return;
            }
            check_term(&mut term, s, &mut stats, "fov-rolloff");
        },
    );
    stats.report("fov-rolloff");
    assert!(stats.checked > 5 * STATES);
}

#[test]
fn kelly_rolloff_partials_match_finite_differences() {
    let mut stats = Stats::default();
    let mut rng = rng(16);
    for_states(
        17,
        STATES,
        |s| lit(s) && s.sun_fraction > 0.5,
        |s| {
            use rand::RngExt;
            // kappa over the range other tools use (0.01-1) and exponents 1-4: the loss
            // exp(-c^k/kappa) then spans 0 to nearly 1 over the drawn incidences.
            let kappa = 10f64.powf(rng.random_range(-2.0..0.0));
            let exponent = rng.random_range(1.0..4.0);
            let mut term = KellyRolloff::new(kappa, exponent).unwrap();
            let mut d = [0.0; 2];
            let sens = term.partials(&s.pd, 0, &s.scene(), &mut d);
            let value = |st: &State| term.value(&st.pd, 0, &st.scene());
            check_sensitivity(s, &sens, &value, &mut stats, "fov-rolloff (Kelly)");
            // Parameter steps relative to the value: kappa spans 0.01-1, and a step of 1e-5
            // absolute is 0.1 % of the smallest, where exp(-c^k/kappa) curves strongly.
            let scene = s.scene();
            for (k, &analytic) in d.iter().enumerate() {
                let p0 = term.parameters()[k].value;
                let h = 1e-6 * p0;
                let mut at = |p: f64| {
                    term.parameters_mut()[k].value = p;
                    term.value(&s.pd, 0, &scene)
                };
                let fd = (at(p0 + h) - at(p0 - h)) / (2.0 * h);
                at(p0);
                stats.check(&format!("fov-rolloff (Kelly) d/dp[{k}]"), analytic, fd);
            }
        },
    );
    stats.report("fov-rolloff (Kelly)");
    assert!(stats.checked > 5 * STATES);
}

#[test]
fn kelly_rolloff_matches_its_equation() {
    // K(c) = 1 - exp(-c^2/0.1): 0.67 % low at 45 deg, 8.2 % at 60, 31 % at 70.
    let term = KellyRolloff::new(0.1, 2.0).unwrap();
    for (deg, loss) in [(45.0, 0.006738), (60.0, 0.082085), (70.0, 0.310_436)] {
        let c = f64::cos(f64::to_radians(deg));
        assert!(
            ((1.0 - term.factor(c)) - loss).abs() < 1e-5,
            "{deg}: {}",
            1.0 - term.factor(c)
        );
    }
    assert_eq!(term.factor(-0.1), 0.0);
    assert!(KellyRolloff::new(0.0, 2.0).is_err());
    assert!(KellyRolloff::new(0.1, -1.0).is_err());
}

#[test]
fn dark_offset_partials_match_finite_differences() {
    let mut stats = Stats::default();
    for_states(8, STATES, State::away_from_kinks, |s| {
        let mut term = DarkOffset::new(&[0.02, -0.01, 0.005]);
        let mut d = [0.0; 3];
        let sens = term.partials(&s.pd, 0, &s.scene(), &mut d);
        assert_eq!(sens.value_v, 0.02);
        assert_eq!(d, [1.0, 0.0, 0.0]);
        check_term(&mut term, s, &mut stats, "dark-offset");
    });
    stats.report("dark-offset");
}

#[test]
fn time_offset_partials_match_finite_differences() {
    let mut stats = Stats::default();
    let mut rng = rng(9);
    for_states(10, STATES, lit, |s| {
        use rand::RngExt;
        let s = State {
            sun_fraction: 1.0,
            ..s.clone()
        };
        let mut term = TimeOffset::new(rng.random_range(-2.0..2.0));
        check_term(&mut term, &s, &mut stats, "time-offset");
    });
    stats.report("time-offset");
}

#[test]
fn time_offset_is_first_order_of_the_delayed_sun() {
    // The term equals C n^T (s(t - delta) - s(t)) to first order: compare with the exact
    // rotation over delta for a small delta (second-order remainder ~ (w delta)^2).
    for_states(11, STATES, lit, |s| {
        let s = State {
            sun_fraction: 1.0,
            sun_distance_factor: 1.0,
            ..s.clone()
        };
        let delta = 0.05;
        let term = TimeOffset::new(delta);
        let first = term.value(&s.pd, 0, &s.scene());
        // A(t - delta) = exp(+[w x] delta) A(t) for constant body rate w.
        let later = s.with_attitude_error(&(-s.rate_body_rad_s * delta));
        let exact = s.pd.scale_v * s.pd.n_body.dot(&(later.attitude * s.sun_gcrf))
            - s.pd.scale_v * s.cos_sun();
        let w_delta = s.rate_body_rad_s.norm() * delta;
        // Second-order remainder bound: C |w delta|^2 / 2, with a factor 2 for safety.
        assert!((first - exact).abs() <= s.pd.scale_v * w_delta * w_delta);
    });
}

#[test]
fn albedo_gain_partials_match_finite_differences() {
    let mut stats = Stats::default();
    for gain in [0.0, 0.6, 1.3] {
        let mut term = AlbedoGain::new(gain, AlbedoPartials::Included);
        for_states(5, STATES, State::away_from_kinks, |s| {
            check_term(&mut term, s, &mut stats, "albedo-gain");
        });
    }
    stats.report("albedo-gain");
    assert!(
        stats.checked > STATES,
        "albedo-gain states should see cells"
    );
}

/// With gain `g`, albedo plus albedo-gain is `g` times the albedo alone.
#[test]
fn albedo_gain_rescales_the_albedo_term() {
    for_states(6, 50, State::away_from_kinks, |s| {
        let scene = s.scene();
        let albedo = Albedo {
            partials: AlbedoPartials::Included,
        };
        let mut with = MeasurementModel::new(vec![s.pd]);
        with.add_term(albedo).unwrap();
        with.add_term(AlbedoGain::new(0.25, AlbedoPartials::Included))
            .unwrap();
        let alone = albedo.value(&s.pd, 0, &scene);
        let both = with.evaluate(0, &scene).unwrap();
        assert!((both - 0.25 * alone).abs() <= 1e-12 * alone.abs().max(1.0));
    });
}

#[test]
fn temperature_gain_partials_match_finite_differences() {
    let mut stats = Stats::default();
    let temperatures = [35.0, -12.5];
    for_states(13, STATES, State::away_from_kinks, |s| {
        let scene = Scene {
            temperature_c: &temperatures,
            ..s.scene()
        };
        let mut gain = Temperature::per_photodiode(&[0.002, -0.004], 20.0);
        let mut d = [0.0; 2];
        let g = gain.gain_partials(1, &scene, &mut d);
        assert_eq!(g, gain.gain(1, &scene));
        assert_eq!(g, 1.0 - 0.004 * (-12.5 - 20.0));
        assert_eq!(d[0], 0.0);
        let k0 = gain.parameters()[1].value;
        let mut at = |k: f64| {
            gain.parameters_mut()[1].value = k;
            gain.gain(1, &scene)
        };
        let fd = (at(k0 + H) - at(k0 - H)) / (2.0 * H);
        stats.check("temperature dg/dk", d[1], fd);
        let unknown = Scene {
            temperature_c: &[f64::NAN, f64::NAN],
            ..s.scene()
        };
        assert_eq!(
            gain.gain(1, &unknown),
            1.0,
            "no temperature: the scale at 20 C"
        );
    });
    stats.report("temperature gain");
}

#[test]
fn scale_drift_gain_partials_match_finite_differences() {
    let mut stats = Stats::default();
    for_states(12, STATES, State::away_from_kinks, |s| {
        let scene = s.scene();
        let mut gain = ScaleDrift::per_photodiode(&[0.03, -0.02]);
        let mut d = [0.0; 2];
        let g = gain.gain_partials(1, &scene, &mut d);
        assert_eq!(g, gain.gain(1, &scene));
        assert_eq!(d[0], 0.0);
        let k0 = gain.parameters()[1].value;
        let mut at = |k: f64| {
            gain.parameters_mut()[1].value = k;
            gain.gain(1, &scene)
        };
        let fd = (at(k0 + H) - at(k0 - H)) / (2.0 * H);
        stats.check("scale-drift dg/dk", d[1], fd);
    });
    stats.report("scale-drift gain");
}

#[test]
fn saturation_stage_partials_match_finite_differences() {
    use rand::RngExt;
    let mut stats = Stats::default();
    let mut rng = rng(13);
    let mut clipped = 0;
    for _ in 0..STATES {
        let max_v: f64 = rng.random_range(2.0..4.0);
        let mut y: f64 = rng.random_range(0.0..6.0);
        while (y - max_v).abs() < 0.01 {
            y = rng.random_range(0.0..6.0);
        }
        let mut stage = Saturation::shared(max_v);
        let mut d = [0.0];
        let (out, dy) = stage.apply_partials(0, y, &mut d);
        assert_eq!(out, stage.apply(0, y));
        clipped += usize::from(dy == 0.0);
        stats.check("saturation d/dy", dy, central(|h| stage.apply(0, y + h), H));
        let mut at = |m: f64| {
            stage.parameters_mut()[0].value = m;
            stage.apply(0, y)
        };
        let fd = (at(max_v + H) - at(max_v - H)) / (2.0 * H);
        stats.check("saturation d/dmax", d[0], fd);
    }
    stats.report("saturation stage");
    assert!(
        clipped > 10 && clipped < STATES - 10,
        "both sides of the clip exercised"
    );
}

/// A model with every photodiode effect; the state's photodiode is number 2 (index 1).
fn full_model(s: &State, max_v: f64) -> MeasurementModel {
    let other = Photodiode::from_az_el_deg(3.7, 10.0, 5.0, 0.015);
    let mut model = MeasurementModel::cosine(vec![other, s.pd, other]);
    model
        .add_term(Albedo {
            partials: AlbedoPartials::Included,
        })
        .unwrap();
    model
        .add_term(FovRolloff::from_deg(55.0, 85.0).unwrap())
        .unwrap();
    model
        .add_term(DarkOffset::new(&[0.01, 0.02, 0.03]))
        .unwrap();
    model.add_term(Penumbra).unwrap();
    model.add_term(TimeOffset::new(0.7)).unwrap();
    model
        .add_gain(ScaleDrift::per_photodiode(&[0.01, -0.03, 0.02]))
        .unwrap();
    model.add_stage(Saturation::shared(max_v)).unwrap();
    model
}

fn model_value(model: &mut MeasurementModel, s: &State) -> f64 {
    model.photodiodes_mut()[1] = s.pd;
    model.evaluate(1, &s.scene()).unwrap()
}

#[test]
fn full_model_partials_match_finite_differences() {
    use rand::RngExt;
    let mut stats = Stats::default();
    let mut rng = rng(14);
    let mut clipped = 0;
    let (start, cutoff) = (55f64.to_radians(), 85f64.to_radians());
    let accept = |s: &State| {
        let theta = s.cos_sun().clamp(-1.0, 1.0).acos();
        s.away_from_kinks() && (theta - start).abs() > 0.01 && (theta - cutoff).abs() > 0.01
    };
    for_states(15, STATES, accept, |s| {
        let probe = full_model(s, 100.0);
        let pre = probe.pre_stage_output(1, &s.scene()).unwrap();
        // Clip about a quarter of the lit samples, never within 0.01 V of the clip.
        let max_v = if rng.random_bool(0.25) {
            pre - 0.05
        } else {
            pre + rng.random_range(0.05..1.0)
        };
        let mut model = full_model(s, max_v);
        let p = model.partials(1, &s.scene()).unwrap();
        clipped += usize::from(p.value_v == max_v);
        let value = |t: &State| {
            let mut m = full_model(t, max_v);
            model_value(&mut m, t)
        };
        let sens = Sensitivity {
            value_v: p.value_v,
            d_attitude: p.d_attitude,
            d_scale: p.d_scale,
            d_normal: p.d_normal,
        };
        check_sensitivity(s, &sens, &value, &mut stats, "model");
        // Every model parameter.
        for k in 0..model.parameter_count() {
            let p0 = model.parameters().nth(k).unwrap().1.value;
            let h = H * p0.abs().max(1.0);
            let mut at = |v: f64| {
                model.set_parameter(k, v).unwrap();
                model.evaluate(1, &s.scene()).unwrap()
            };
            let fd = (at(p0 + h) - at(p0 - h)) / (2.0 * h);
            at(p0);
            stats.check(&format!("model d/dparam[{k}]"), p.d_parameters[k], fd);
        }
        // Azimuth/elevation chain (Eqs. 23-24 generalised).
        let (az, el) = s.pd.az_el_rad();
        let (d_az, d_el) = p.d_az_el(az, el);
        let at_az_el = |a: f64, e: f64| {
            let mut t = s.clone();
            t.pd.n_body = normal_from_az_el(a, e);
            value(&t)
        };
        stats.check("model d/daz", d_az, central(|h| at_az_el(az + h, el), H));
        stats.check("model d/del", d_el, central(|h| at_az_el(az, el + h), H));
    });
    stats.report("full model");
    assert!(clipped > 5, "clipped states exercised: {clipped}");
}

#[test]
fn paper_equations_20_to_24_match_finite_differences() {
    let mut stats = Stats::default();
    for_states(
        16,
        STATES,
        |s| s.cos_sun() > KINK_MARGIN,
        |s| {
            let (az, el) = s.pd.az_el_rad();
            let c = s.pd.scale_v;
            let sun_body = s.attitude * s.sun_gcrf;
            let output = |t: &State, scale: f64, n: &Vector3<f64>| {
                paper::predicted_output(scale, n, &(t.attitude * t.sun_gcrf), 0.0)
            };
            let d_a = paper::d_output_d_attitude(c, &s.pd.n_body, &sun_body);
            for k in 0..3 {
                let e = Vector3::ith(k, 1.0);
                let fd = central(
                    |h| output(&s.with_attitude_error(&(e * h)), c, &s.pd.n_body),
                    H,
                );
                stats.check("Eq. 20", d_a[k], fd);
            }
            let fd = central(|h| output(s, c + h, &s.pd.n_body), H);
            stats.check(
                "Eq. 22",
                paper::d_output_d_scale(&s.pd.n_body, &sun_body),
                fd,
            );
            let fd = central(|h| output(s, c, &normal_from_az_el(az + h, el)), H);
            stats.check(
                "Eq. 23",
                paper::d_output_d_azimuth(c, az, el, &sun_body),
                fd,
            );
            let fd = central(|h| output(s, c, &normal_from_az_el(az, el + h)), H);
            stats.check(
                "Eq. 24",
                paper::d_output_d_elevation(c, az, el, &sun_body),
                fd,
            );
            assert_eq!(paper::d_output_d_gyro_bias(), Vector3::zeros());
            // The general model's direct-Sun term agrees with the paper's functions.
            let s1 = State {
                sun_fraction: 1.0,
                sun_distance_factor: 1.0,
                pd: s.pd.with_fov_half_angle_rad(None),
                ..s.clone()
            };
            let sens = DirectSun::default().partials(&s1.pd, 0, &s1.scene(), &mut []);
            assert!((sens.d_attitude - d_a).norm() < 1e-14 * c);
        },
    );
    stats.report("paper Eqs. 20-24");
}

#[test]
fn direct_path_of_the_provided_terms_equals_the_generic_loop() {
    // Models made only of terms the model knows take the direct path in `partials_into`;
    // `partials_into_generic` is the loop over trait objects. Same operations in the same
    // order: the results must be the same bits (including shadowed and gated samples).
    let models = |pd: Photodiode| {
        let mut penumbra = MeasurementModel::new(vec![pd]);
        penumbra
            .add_term(DirectSun {
                shadow: ShadowMode::Penumbra,
            })
            .unwrap();
        penumbra
            .add_term(Albedo {
                partials: AlbedoPartials::Included,
            })
            .unwrap();
        let mut reversed = MeasurementModel::new(vec![pd]);
        reversed.add_term(Albedo::default()).unwrap();
        reversed.add_term(DirectSun::default()).unwrap();
        [
            MeasurementModel::cosine(vec![pd]),
            MeasurementModel::paper(vec![pd]),
            penumbra,
            reversed,
        ]
    };
    let mut compared = 0;
    for_states(
        11,
        400,
        |_| true,
        |s| {
            for model in models(s.pd) {
                let scene = s.scene();
                let (mut direct, mut generic) = (Partials::default(), Partials::default());
                model.partials_into(0, &scene, &mut direct).unwrap();
                model
                    .partials_into_generic(0, &scene, &mut generic)
                    .unwrap();
                assert_eq!(direct, generic, "{:?}", model.ids());
                compared += 1;
            }
        },
    );
    assert_eq!(compared, 1600);
}
