import json, glob, os
R = '/tmp/judge11/records'
PMAP = {'cubic_stiffness': ['k3'], 'coulomb_friction': ['mu'], 'asymmetric_friction': ['mu_pos', 'mu_neg'],
        'flight_damping': ['c_f'], 'quadratic_drag': ['c2'], 'actuator_lag': ['tau'], 'input_delay': ['delay'],
        'input_offset': ['input_offset'], 'switch_threshold': ['v_th'], 'hard_stop': ['x_stop', 'k_stop'],
        'sensor_lag': ['tau_s'], 'sensor_offset_gain': ['sensor_offset', 'sensor_gain']}
TOOLP = {'sensor_offset': 'b', 'sensor_gain': 'g'}
NOMP = dict(m=1.0, k=200.0, c=2.0)

def within(a, b, tol=0.10):
    return abs(a - b) <= tol * abs(b)

def score(d):
    t = json.load(open(d + '/truth.json')); n = t['name']
    j = json.load(open(d + '/out/diagnosis.json'))
    wall = float(open(d + '/wall.txt').read())
    cause = j['cause']; causes = {c['effect']: c['parameters'] for c in j.get('causes', [])}
    alts = j.get('alternatives') or []
    eff = t['effects']; notes = []; ok = True; pcmp = []
    named = set(causes) | set(alts)
    if t['group'] == 'clean':
        ok = cause == 'none'
    elif t['group'] == 'outside':
        lib = [e for e in causes]
        confident = cause not in ('unexplained', 'ambiguous', 'none') and len(lib) > 0
        ok = not confident
        if confident: notes.append('library effect(s) claimed with confidence: ' + ', '.join(lib))
        if j.get('discovered'): notes.append('discovered: ' + j['discovered']['formula'])
    else:
        for lab in t['labels']:
            if lab == 'parameter_error':
                tn = t['nominal_truth']
                if 'parameter_error' not in named: ok = False; notes.append('parameter_error not named'); continue
                for p, v in causes.get('parameter_error', {}).items():
                    if p in tn and tn[p] != NOMP.get(p):
                        good = within(v, tn[p], 0.10) and within(v - NOMP[p], tn[p] - NOMP[p], 0.10)
                        pcmp.append(f'{p}={v:.4g} (truth {tn[p]:.4g})' + ('' if good else ' X')); ok &= good
                for p in ('m', 'k', 'c'):
                    if tn[p] != NOMP[p] and p not in causes.get('parameter_error', {}):
                        ok = False; notes.append(f'{p} error not found')
                continue
            cand = None
            if lab in causes: cand = lab
            elif lab == 'input_offset' and 'sensor_offset_gain' in causes:
                cand = 'sensor_offset_gain'; notes.append('input offset named as its exact equivalent, a sensor offset')
            elif lab in alts: cand = lab; notes.append(f'{lab} among alternatives of ambiguous')
            if cand is None:
                ok = False; notes.append(f'{lab} not named'); continue
            P = causes.get(cand)
            if P is None:
                c0 = [c for c in j['candidates'] if c['effect'] == cand]
                P = c0[0]['parameters'] if c0 else {}
                notes.append(f'{cand} params from first-round candidate')
            if lab == 'input_offset' and cand == 'sensor_offset_gain':
                tv = eff['input_offset'] / 200.0
                good = within(P['b'], tv) and abs(P['g'] - 1) < 0.01
                pcmp.append(f"b={P['b']:.4g} (truth offset/k={tv:.4g}), g={P['g']:.5g}" + ('' if good else ' X')); ok &= good
                continue
            for p in PMAP[lab]:
                tp = TOOLP.get(p, p)
                v = P.get(tp)
                if v is None: ok = False; pcmp.append(f'{tp} missing X'); continue
                good = within(v, eff[p])
                if p == 'sensor_gain': good = within(v - 1, eff[p] - 1)  # stricter: the deviation within 10 %
                pcmp.append(f'{tp}={v:.5g} (truth {eff[p]:.5g})' + ('' if good else ' X')); ok &= good
        equiv = {'input_offset': {'sensor_offset_gain', 'input_offset', 'asymmetric_friction'}}
        allowed = set(t['labels'])
        for lab in t['labels']:
            allowed |= equiv.get(lab, set())
        extra = [e for e in causes if e not in allowed]
        for e in extra:
            if e == 'parameter_error':
                bad = [f'{p}={v:.4g}' for p, v in causes[e].items() if p in NOMP and not within(v, t['nominal_truth'][p], 0.02)]
                if bad: ok = False; notes.append('extra parameter_error ' + ', '.join(bad))
                else: notes.append('extra parameter_error within 2 % of truth')
            else:
                ok = False; notes.append(f'extra effect claimed: {e} {causes[e]}')
    return dict(name=n, group=t['group'], truth=t['labels'], truth_params=eff | ({'nom': {k: v for k, v in t['nominal_truth'].items() if NOMP.get(k, v) != v}} if t['labels'] == ['parameter_error'] else {}),
                cause=cause, causes={k: {p: round(v, 6) for p, v in P.items()} for k, P in causes.items()}, alternatives=alts,
                discovered=(j.get('discovered') or {}).get('formula'), params='; '.join(pcmp), ok=bool(ok), notes='; '.join(notes),
                wall=wall, elapsed=j.get('elapsed_s'), nrmse_final=j['extended']['nrmse'], floor_ratio=j['extended']['rmse'] / j['noise_floor'])

rows = [score(d.rstrip('/')) for d in sorted(glob.glob(R + '/*/')) if os.path.exists(d + 'out/diagnosis.json')]
json.dump(rows, open('/tmp/judge11/scores.json', 'w'), indent=1)
from collections import defaultdict
tot = defaultdict(lambda: [0, 0])
for r in rows:
    tot[r['group']][1] += 1; tot[r['group']][0] += r['ok']
    print(f"{'PASS' if r['ok'] else 'FAIL'} {r['name']:28s} cause={r['cause']:20s} causes={list(r['causes'])} {r['params']} | {r['notes']} | {r['wall']:.1f}s fr={r['floor_ratio']:.2f}")
for g, (a, b) in tot.items(): print(g, a, '/', b)
