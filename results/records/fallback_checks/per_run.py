"""Per policy and run: successes, departure share, fallbacks, from compare_selection JSONs."""
import gzip, json, sys, collections
for spec in sys.argv[1:]:
  recs = []
  for path in spec.split('+'):
    op = gzip.open if path.endswith('.gz') else open
    with op(path, 'rt') as f:
      recs += json.load(f)['records']
  by = collections.defaultdict(list)
  for r in recs:
    by[(r['policy'], r['run'])].append(r)
  print('==', spec)
  for (pol, run), rs in sorted(by.items(), key=lambda kv: (kv[0][0], str(kv[0][1]))):
    dec = sum(r['length'] for r in rs); dep = sum(r.get('departures', 0) for r in rs)
    fb = sum(r.get('fallback_at') is not None for r in rs) if all('fallback_at' in r for r in rs) else '-'
    print(f"{pol:34s} run {str(run)[-30:]:30s} {sum(r['success'] for r in rs):4d}/{len(rs):4d} dep {dep/max(dec,1):.2f} fallback {fb}")
