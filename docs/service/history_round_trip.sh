#!/bin/sh
# The drive-history round trip of the README ("Drives, history and trend"), with curl against a running
# service: BASE=http://127.0.0.1:8000 sh docs/service/history_round_trip.sh
# Four records of one drive ("press-7") taken a few weeks apart, simulated here with a growing width
# (4.0, 4.6, 5.3, 5.8 mm) and 40 dB of white noise, are identified with the drive's name and date; then
# the history and the trend towards a 9 mm limit are read back.
set -eu
BASE="${BASE:-http://127.0.0.1:8000}"
json() { python3 -c "import json,sys; d=json.load(sys.stdin); print($1)"; }
job=$(curl -sf -X POST "$BASE/v1/pattern-sets" -H 'Content-Type: application/json' \
      -d '{"channel": "v2", "c": 1.0}' | json 'd["job_id"]')
until [ "$(curl -sf "$BASE/v1/jobs/$job" | json 'd["state"]')" = done ]; do sleep 1; done
for pair in 2026-06-01:0.0040 2026-07-13:0.0046 2026-08-24:0.0053 2026-10-05:0.0058; do
  day=${pair%%:*}; K=${pair##*:}
  curl -sf -X POST "$BASE/v1/simulate" -H 'Content-Type: application/json' -d "{\"K\": $K}" \
  | python3 -c "
import json, sys, random
rec = json.load(sys.stdin)
rng = random.Random('$day')
for name, xs in rec['channels'].items():   # 40 dB of white noise, as a bench records
    rms = (sum(x * x for x in xs) / len(xs)) ** 0.5
    rec['channels'][name] = [x + rng.gauss(0.0, rms * 0.01) for x in xs]
rec['conditions'].pop('K')                  # the width is what is sought
rec.update(asset='press-7', measured_at='${day}T08:00:00Z')
print(json.dumps({'record': rec, 'channel': 'v2'}))" \
  | curl -sf -X POST "$BASE/v1/identify" -H 'Content-Type: application/json' --data-binary @- \
  | json '"identified", d["measured_at"], "K = %.2f +- %.2f mm" % (d["continuous"]["K"] * 1e3, d["continuous"]["sigma_K"] * 1e3)'
done
curl -sf "$BASE/v1/assets"; echo
curl -sf "$BASE/v1/assets/press-7/history" | json '"\n".join("%s %s K = %.2f mm" % (p["measured_at"], p["kind"], p["K"] * 1e3) for p in d["points"])'
curl -sf "$BASE/v1/assets/press-7/trend?limit=0.009" | python3 -m json.tool
curl -sf -o press-7-trend.png "$BASE/v1/assets/press-7/trend/figure?limit=0.009" && echo "figure: press-7-trend.png"
