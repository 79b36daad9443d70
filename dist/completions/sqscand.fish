complete -c sqscand -l config -d 'Configuration file [default: /etc/sqscan/sqscand.toml if it exists, else the embedded simulator configuration]' -r -F
complete -c sqscand -l socket -d 'Unix socket to listen on (overrides the file\'s server.socket)' -r -F
complete -c sqscand -l models-dir -d 'Directory of object models (overrides the file\'s server.models_dir) [default: $SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists]' -r -F
complete -c sqscand -l replay -d 'Serve the recorded sweeps in DIR instead of scanning (overrides the file\'s backend): the daemon\'s recordings (sweep-*.json and .pcd) and other organized PCD files with a viewpoint (and, in a build with the mcap feature, MCAP files with a ROS 2 PointCloud2)' -r -F
complete -c sqscand -l replay-speed -d 'With --replay: 1 replays at the recorded pace, 2 twice as fast, 0 as fast as asked' -r
complete -c sqscand -l replay-loop -d 'With --replay: start again after the last sweep instead of stopping there'
complete -c sqscand -l replay-step -d 'With --replay: serve one recorded sweep a request, the next each time a client asks for a fresh one (`sqscan scan`, or a `find` whose newest sweep is too old), at once; the file\'s acquisition mode becomes on_demand'
complete -c sqscand -l check -d 'Run every start-up check (configuration, models, scene or calibration, serial devices) and exit'
complete -c sqscand -l probe -d 'With --check: also open the configured PTU and sensor and say what they report (the PTU is not homed or moved; an SQPF sensor is started for one profile); fails naming the device that does not answer'
complete -c sqscand -s h -l help -d 'Print help (see more with \'--help\')'
complete -c sqscand -s V -l version -d 'Print version'
