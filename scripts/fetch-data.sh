#!/usr/bin/env bash
# The shared sample clouds the README, the guides and the tests read from ../shared/data, fetched
# from their public sources at the commits ../shared/data/SOURCES.md gives, each checked by its
# SHA-256. Run it once, beside the checkout:
#
#     scripts/fetch-data.sh ../shared/data
#
# Most files are downloaded as they are. Two are derived from a downloaded file, here, by a
# rule that gives the shared file byte for byte: bun.conf (the lines of Stanford's bun.conf for
# the five scans kept) and ouster_os1.conf (the Ouster SDK's KITTI poses as quaternions). The
# three Ouster sweeps were decoded from a pcap by the Ouster SDK, which this script does not
# install: it downloads the pcap and its sensor metadata and says how to decode them.
# A file already in DIR with the right checksum is left alone. Exit status 1 if a download or a
# checksum fails; the sweeps not yet decoded are listed, and do not fail the run.
# tests/tests/data_sources.rs checks this manifest against the files in ../shared/data.
set -euo pipefail

if [ $# -ne 1 ] || [ "$1" = "-h" ] || [ "$1" = "--help" ]; then
    echo "usage: scripts/fetch-data.sh DIR   (the tests read ../shared/data, beside the checkout)" >&2
    exit 2
fi
dir=$1
mkdir -p "$dir"

# file, SHA-256, how it is made, repository, commit, path in the repository.
# how: `download` (as it is), `subset` (bun.conf's lines for the scans here), `poses` (KITTI
# poses to the bun.conf convention), `decoded` (an Ouster sweep, decoded from the pcap by the
# Ouster SDK), `source` (a file the Ouster sweeps are decoded from, kept in DIR/ouster-source).
manifest() {
    cat <<'MANIFEST'
bun000.ply 7d48f9fdf917311de680d074edce8aff25a4b9bfd87be9301822dace811209fb download ksnabb/stan_bun 3f304b79052f2023f22ef8e5d15b7e571665ac16 bunny/data/bun000.ply
bun270.ply 51cec23127a26bce6e96ac4ca17b12c8e57e365d63d98e919501199f7d4d78c8 download ksnabb/stan_bun 3f304b79052f2023f22ef8e5d15b7e571665ac16 bunny/data/bun270.ply
bun315.ply 3715a3b19d00874b9d25b2c29fea228d9d275d5d44607b21d2903e90ce919f6e download ksnabb/stan_bun 3f304b79052f2023f22ef8e5d15b7e571665ac16 bunny/data/bun315.ply
top3.ply ccded0886e91bd3d2653f671c3bd45fad0228d2be54b9aa98f0ee6de60cbcbb2 download ksnabb/stan_bun 3f304b79052f2023f22ef8e5d15b7e571665ac16 bunny/data/top3.ply
ear_back.ply e8b78473ec43b6cefe210fb4638c3666b2cf74d81ae552d832a6a600af63ca24 download ksnabb/stan_bun 3f304b79052f2023f22ef8e5d15b7e571665ac16 bunny/data/ear_back.ply
bun_zipper.ply e5bfa06a738e5c59e4c147c6edc17df99e09735daa3432391e841fba825a2a33 download ksnabb/stan_bun 3f304b79052f2023f22ef8e5d15b7e571665ac16 bunny/reconstruction/bun_zipper.ply
bun.conf 303b81977f562d6a3a22809c9f292f2c2747277f16ff35edb5548959076fbe03 subset ksnabb/stan_bun 3f304b79052f2023f22ef8e5d15b7e571665ac16 bunny/data/bun.conf
car6.pcd 0abbde3ff8d07972a425b0a81530e905490d7fe38b248d7fb2b40d20fe00c97d download PointCloudLibrary/pcl 1fdb03883eab28f642e938d9bf4d317903212cb4 test/car6.pcd
milk.pcd a9eb086e321f7dcf03c43da8148b3d25e09119d83aaaeafa9cb23d835e64b766 download PointCloudLibrary/pcl 1fdb03883eab28f642e938d9bf4d317903212cb4 test/milk.pcd
lamppost.pcd b585826c91a8f681fed0a617455723049beddca21e3ca59af6aa61227eec1a12 download PointCloudLibrary/pcl 1fdb03883eab28f642e938d9bf4d317903212cb4 test/lamppost.pcd
rops_cloud.pcd 9bed3d9573620aaa228a63f59e85189e0c8a01204fb09ee61f17fc6ae26f2f4d download PointCloudLibrary/pcl 1fdb03883eab28f642e938d9bf4d317903212cb4 test/rops_cloud.pcd
cturtle.pcd 95051d3e500edc0d4ab44bfc702c5d95940bc7978c071c518ec2e5f72ff82c99 download PointCloudLibrary/pcl 1fdb03883eab28f642e938d9bf4d317903212cb4 test/cturtle.pcd
five_people.pcd 6f1ca66de5f88b035f6c4d16a2e737b6b1e0e98020fda91e7b2b8efae59ae1b7 download PointCloudLibrary/pcl 1fdb03883eab28f642e938d9bf4d317903212cb4 test/five_people.pcd
office1.pcd b34da6814cd5979dc7a0648655301f0d3f6fb8275fa1e627c7f7f5b5ca78c201 download PointCloudLibrary/pcl 1fdb03883eab28f642e938d9bf4d317903212cb4 test/office1.pcd
simple.las a0570ef57b685b77a6d3e3992cbdfeecdb2c3065d3780bbeaba490818258b734 download laspy/laspy fbc5b375f9dad6bae499a81ca436bee361ecf047 tests/data/simple.las
vegetation_1_3.las c3e882a096b12cecd1c7b803ba8e69d7bc1d327bbc1df05c02375654e097dfcb download laspy/laspy fbc5b375f9dad6bae499a81ca436bee361ecf047 tests/data/vegetation_1_3.las
autzen_trim.laz 75867b3e75cfc3c2e96da9f753c04c9fbaa6a59468dea13e2859f3109b38bd66 download laspy/laspy fbc5b375f9dad6bae499a81ca436bee361ecf047 tests/data/autzen_trim.laz
ouster_os1.conf 28d6b3cd60b6a348ef6beb9854cac83be1c9f041d8cd0c08a4b2b6bbf67caa13 poses ouster-lidar/ouster-sdk 46b7bceee7995914e2f3f3facf4d78418335b2d7 tests/pcaps/OS-1-128_v2.3.0_1024x10_lb_n3_poses_kitti.txt
ouster_os1_0.pcd b0be82958db3f7927bda48b05b6e0381fad0f658fde66f18dbb9256b7da25664 decoded ouster-lidar/ouster-sdk 46b7bceee7995914e2f3f3facf4d78418335b2d7 tests/pcaps/OS-1-128_v2.3.0_1024x10_lb_n3.pcap
ouster_os1_1.pcd 546f8ac1529ab865e5dc40bcd69526639d5e102628e8723691eee32bb9fb22cd decoded ouster-lidar/ouster-sdk 46b7bceee7995914e2f3f3facf4d78418335b2d7 tests/pcaps/OS-1-128_v2.3.0_1024x10_lb_n3.pcap
ouster_os1_2.pcd 642eb5c101eb3124db3774ecf8da01e5462c35506df754509825626e5674e2a6 decoded ouster-lidar/ouster-sdk 46b7bceee7995914e2f3f3facf4d78418335b2d7 tests/pcaps/OS-1-128_v2.3.0_1024x10_lb_n3.pcap
ouster-source/OS-1-128_v2.3.0_1024x10_lb_n3.pcap cad3545a6246c2638ad02f3884f880143496127192eca3329b42aac92a06fba5 source ouster-lidar/ouster-sdk 46b7bceee7995914e2f3f3facf4d78418335b2d7 tests/pcaps/OS-1-128_v2.3.0_1024x10_lb_n3.pcap
ouster-source/OS-1-128_v2.3.0_1024x10.json 3df9e8ebbd62c79aaea34981b0c838d6ada847d9f9b5d0af95770a4036057e49 source ouster-lidar/ouster-sdk 46b7bceee7995914e2f3f3facf4d78418335b2d7 tests/pcaps/OS-1-128_v2.3.0_1024x10.json
MANIFEST
}

sha() { sha256sum "$1" | cut -d' ' -f1; }

# `curl` of one file of a repository at a commit, to $2.
download() {
    local repo=$1 commit=$2 path=$3 out=$4
    curl --fail --silent --show-error --location --retry 3 \
        "https://raw.githubusercontent.com/$repo/$commit/$path" --output "$out"
}

# Stanford's bun.conf names ten scans; the shared data has five of them (and the camera line).
subset_conf() {
    grep -E '^(camera |bmesh (bun000|bun270|top3|bun315|ear_back)\.ply )' "$1"
}

# The Ouster SDK's KITTI poses (a 3 x 4 matrix a line, sensor to world) as bun.conf's lines:
# x_world = R(q)^T x + t, so q is the conjugate of the rotation's quaternion (scalar last); a
# zero is written without its sign.
kitti_to_conf() {
    awk 'NF == 12 {
        w = sqrt(1 + $1 + $6 + $11) / 2
        x = ($10 - $7) / (4 * w); y = ($3 - $9) / (4 * w); z = ($5 - $2) / (4 * w)
        printf "bmesh ouster_os1_%d.pcd %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n", n++, \
            $4, $8, $12, (x == 0 ? 0 : -x), (y == 0 ? 0 : -y), (z == 0 ? 0 : -z), w
    }' "$1"
}

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failed=0
undecoded=()
while read -r file sum how repo commit path; do
    out="$dir/$file"
    if [ -f "$out" ] && [ "$(sha "$out")" = "$sum" ]; then
        echo "ok       $file (already there)"
        continue
    fi
    made="$tmp/made"
    case $how in
        download | source)
            mkdir -p "$(dirname "$out")"
            download "$repo" "$commit" "$path" "$made" || { failed=1; continue; } ;;
        subset)
            download "$repo" "$commit" "$path" "$tmp/upstream" || { failed=1; continue; }
            subset_conf "$tmp/upstream" >"$made" ;;
        poses)
            download "$repo" "$commit" "$path" "$tmp/upstream" || { failed=1; continue; }
            kitti_to_conf "$tmp/upstream" >"$made" ;;
        decoded)
            undecoded+=("$file")
            continue ;;
    esac
    if [ "$(sha "$made")" != "$sum" ]; then
        echo "BAD      $file: SHA-256 $(sha "$made"), expected $sum" >&2
        failed=1
        continue
    fi
    mv "$made" "$out"
    echo "fetched  $file ($how, $repo@${commit:0:12} $path)"
done < <(manifest)

if [ ${#undecoded[@]} -gt 0 ]; then
    cat <<EOF

Not made here: ${undecoded[*]}.
They are three consecutive sweeps decoded from $dir/ouster-source/OS-1-128_v2.3.0_1024x10_lb_n3.pcap
with its sensor metadata OS-1-128_v2.3.0_1024x10.json (both downloaded above, from
ouster-lidar/ouster-sdk at 46b7bceee7995914e2f3f3facf4d78418335b2d7) by the Ouster SDK's own XYZ
table: each scan's RANGE field through XYZLut(metadata), destaggered, written as an organized
1,024 x 128 PCD (DATA binary, fields x y z float32, metres, row = beam, column = azimuth, NaN
where a slot has no return, VIEWPOINT 0 0 0 1 0 0 0), sweeps 0, 1 and 2 of the pcap. Put them in
$dir and run this again to check them; until then the tests that read them fail.
EOF
fi
exit $failed
