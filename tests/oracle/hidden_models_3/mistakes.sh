#!/bin/sh
# Recreates the user-mistake cases of README.md (bug 6, 7) in /tmp/r3/mist and runs them.
set -u
M=$(cd "$(dirname "$0")" && pwd); H=${H:-/tmp/htfid-r3/htfid}
mkdir -p /tmp/r3/mist && cd /tmp/r3/mist
th() { sed "s|file = \"relay_oscillator.toml\"|file = \"$1.toml\"|" $M/theory-relay_oscillator.toml > th-$1.toml; echo "--- $1"; $H -q theory th-$1.toml --out o-$1; echo "rc=$?"; }
sed 's/v = "(passive + F) \/ m"/v = "(pasive + F) \/ m"/' $M/relay_oscillator.toml > typo.toml; th typo
sed 's/delta = { value = 0.05, /delta = { value = 0.5, /' $M/relay_oscillator.toml > nofire.toml; th nofire
python3 - "$M" <<'PY'
import sys; M=sys.argv[1]; s=open(M+'/relay_oscillator.toml').read()
open('wrongdir.toml','w').write(s.replace('when = "x - delta"\ndirection = "rising"','when = "x - delta"\ndirection = "falling"'))
open('badperiod.toml','w').write(s.replace('a * cos(2*pi*t/T)','a * cos(pi*t/T)'))
open('baddir.toml','w').write(s.replace('direction = "falling"','direction = "down"'))
c=open(M+'/contact_pair.toml').read()
open('nopos.toml','w').write(c.replace('pos(d)^1.5','d^1.5'))
PY
th wrongdir; th badperiod; th baddir
sed "s|file = \"contact_pair.toml\"|file = \"nopos.toml\"|" $M/theory-contact_pair.toml > th-nopos.toml; echo "--- nopos"; $H -q theory th-nopos.toml --out o-nopos; echo "rc=$?"
sed "s|outputs = \[\"x\"\]|outputs = [\"pos\"]|; s|file = \"relay_oscillator-record.csv\"|file = \"$M/relay_oscillator-record.csv\"|" $M/estimate-relay_oscillator.toml > est-col.toml
echo "--- wrong column"; $H -q estimate est-col.toml --out o-col; echo "rc=$?"
