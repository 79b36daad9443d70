# Print an optspec for argparse to handle cmd's options that are independent of any subcommand.
function __fish_sqscan_global_optspecs
    string join \n h/help V/version
end

function __fish_sqscan_needs_command
    # Figure out if the current invocation already has a command.
    set -l cmd (commandline -opc)
    set -e cmd[1]
    argparse -s (__fish_sqscan_global_optspecs) -- $cmd 2>/dev/null
    or return
    if set -q argv[1]
        # Also print the command, so this can be used to figure out what it is.
        echo $argv[1]
        return 1
    end
    return 0
end

function __fish_sqscan_using_subcommand
    set -l cmd (__fish_sqscan_needs_command)
    test -z "$cmd"
    and return 1
    contains -- $cmd[1] $argv
end

complete -c sqscan -n "__fish_sqscan_needs_command" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_needs_command" -s V -l version -d 'Print version'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "simulate" -d 'Simulate one sweep of a scene: writes cloud.ply, cloud.pcd, range.png and truth.json'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "show-model" -d 'Sample a model\'s surface into a PLY file (one colour a part)'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "info" -d 'Print a point cloud file\'s point count, finite points, organization and bounding box'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "detect" -d 'Find an object in a point cloud file; prints one JSON object'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "learn" -d 'Learn a model by showing the object: recover its superquadric from one scan'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "eval" -d 'Measure detection rate, false "found" rate, time and pose error on simulated sweeps'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "eval-real" -d 'Measure the detector on real scans labelled by object class: recall, false answers, time'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "mock" -d 'Run mock devices on pseudo-terminals (use their paths like hardware)'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "ptu" -d 'Bring-up tool for a pan-tilt unit: status, home, move, sweep'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "sensor" -d 'Bring-up tool for a profile sensor: grab profiles and print their statistics'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "find" -d 'Ask the daemon where an object is (from a recent sweep, or the next one)'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "scan" -d 'Ask the daemon for a sweep now; prints it when complete'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "cloud" -d 'Fetch a recent sweep\'s points from the daemon into a PCD file'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "watch" -d 'Print every sweep\'s detections of the given objects until interrupted'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "status" -d 'The daemon\'s devices, last sweep, rates and faults'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "models" -d 'The objects the daemon knows'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "completions" -d 'Print a shell completion script for sqscan (or, with --daemon, sqscand)'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "man" -d 'Write the manual pages of sqscan (one a subcommand) and sqscand into a directory'
complete -c sqscan -n "__fish_sqscan_needs_command" -f -a "help" -d 'Print this message or the help of the given subcommand(s)'
complete -c sqscan -n "__fish_sqscan_using_subcommand simulate" -l models-dir -d 'Directory of object models [default: $SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand simulate" -l out -d 'Output directory (created if missing)' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand simulate" -l seed -d 'Seed of the sensor noise and dropout' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand simulate" -l columns -d 'Override the scene\'s sensor columns (e.g. 1536 for a full-resolution sensor)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand simulate" -l json -d 'Print one JSON object (the sweep\'s size and the files written) instead of a line of text'
complete -c sqscan -n "__fish_sqscan_using_subcommand simulate" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand show-model" -l models-dir -d 'Directory of object models [default: $SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand show-model" -l out -d 'Output PLY file' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand show-model" -l spacing -d 'Distance between surface samples (m)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand show-model" -l json -d 'Print one JSON object (the model, its parts and the points written) instead of a line of text'
complete -c sqscan -n "__fish_sqscan_using_subcommand show-model" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand info" -l json -d 'Print one JSON object'
complete -c sqscan -n "__fish_sqscan_using_subcommand info" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l models-dir -d 'Directory of object models [default: $SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l model -d 'Model name (looked up in the models directory) or model file' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l cloud -d 'Point cloud file (.pcd, .ply, text with x y z per line, or .mcap in a build with the mcap feature)' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l seed -d 'Seed of every random choice of the search' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l out -d 'Write the input cloud with the detected surfaces added in colour (PLY)' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l max-range -d 'Ignore points farther than this from the viewpoint (m), e.g. a wall behind the table' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l viewpoint -d 'Sensor position "x,y,z" in the cloud\'s frame [default: the file\'s VIEWPOINT, else the origin]' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l hypotheses -d 'Hypotheses for the (largest) part [default: the model\'s m, else from the scene\'s extent]' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l trials -d 'RANSAC trials per hypothesis' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l repeat -d 'Run the detection N times on the cloud in this process and report the fastest run, for benchmarks: the runs after the first are warm, as in the daemon. Every run must give the same answer' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l grasps -d 'Give every found object up to N grasps of a parallel gripper, best first, checked against the cloud (docs/GRASPS.md)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l gripper -d 'The gripper\'s settings: a TOML file of the [gripper] table\'s keys [default: a Robotiq 2F-85-class gripper]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l all -d 'Report every accepted instance that does not overlap a better one'
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l keep-plane -d 'Keep the dominant plane instead of removing it'
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -l ignore-colour -d 'Do not check a found object\'s colours against the model\'s (where both have colours)'
complete -c sqscan -n "__fish_sqscan_using_subcommand detect" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l models-dir -d 'Directory of object models [default: $SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l cloud -d 'Point cloud file (.pcd, .ply, or text with x y z per line); several files are sweeps of one view (organized clouds of the same size, the scene and the sensor still), learned from their per-pixel median, which cuts the noise by about the square root of their number' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l name -d 'Name of the learned model' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l parts -d 'Superquadric parts (1, 2 or 3)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l out -d 'Model file to write [default: MODELS_DIR/NAME.toml, unless that is the package\'s /usr/share/sqscan/models]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l label -d 'Use the points labelled as object N (mOSD labels: label >= 20 and label / 10 == N); the table is fitted to the points labelled 1-9' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l at -d 'Learn the object shown by a point "x,y,z" of the cloud\'s frame: the connected points clear of the supporting plane (over twice its noise band) nearest to it (within 5 cm), cut from what touches it where the two meet in a concave crease' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l box -d 'Learn the points clear of the supporting plane (over twice its noise band) inside the box "x0,y0,z0,x1,y1,z1" (its opposite corners, in the cloud\'s frame)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l viewpoint -d 'Sensor position "x,y,z" [default: the file\'s VIEWPOINT, else the origin]' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l up -d 'Up direction "x,y,z" when there is no supporting plane in the cloud' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l max-range -d 'Ignore points farther than this from the viewpoint (m)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l cost -d 'Residual minimised' -r -f -a "radial\t'Radial Euclidean distance (m)'
solina\t'Paper eq. 2 with Solina\'s volume factor sqrt(a1 a2 a3)'
normal\t'First-order geometric distance along the surface normal (m)'"
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l shape -d 'Shapes to choose from' -r -f -a "auto\t'A body of revolution unless the general shape fits the view clearly (5 %) better'
general\t'Any superquadric'
revolution\t'A body of revolution (for a round object whose view does not tell: a segmented can)'"
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l simulate -d 'Instead of a cloud: simulate the named shipped model alone on the table (fig3 rig, 2 mm noise), learn it and print the errors against the truth as JSON' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l seed -d 'Noise seed of --simulate' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l sweeps -d 'Sweeps of the one view --simulate takes, learned from their per-pixel median' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l rpy -d 'How --simulate sets the model on the table, "roll,pitch,yaw" in degrees [default: slender parts on their side at yaw 30, the others upright at yaw 25]' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l force -d 'Replace an existing model file'
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l segmented -d 'The cloud holds the object only (already segmented): no plane removal, no clustering; with --up it stands on the plane across up at its lowest points'
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l no-mirror -d 'Do not add the visible points mirrored through the vertical axis'
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l silhouette -d 'Free space just outside the points\' silhouette seen from the viewpoint (segmented clouds from a camera with a known position)'
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -l no-rays -d 'Fit the distance to the nearest surface in the final stages, not the distance along the sensor\'s ray through each point (for a cloud whose viewpoint is not known)'
complete -c sqscan -n "__fish_sqscan_using_subcommand learn" -s h -l help -d 'Print help (see more with \'--help\')'
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l models-dir -d 'Directory of object models [default: $SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l scene -d 'Scene file (scenes/*.toml)' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l model -d 'Model name or file to detect' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l trials -d 'Trials: each re-simulates the sweep with new noise and searches with a new seed' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l seed -d 'First seed (trial k uses seed + k for both the noise and the search)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l truth-object -d 'The scene object the model is (its pose is the truth) [default: the object of the same model, else the one with the model\'s first part\'s shape]; for a learned model' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l model-in-object -d 'The model\'s frame in the truth object\'s frame, "x,y,z,qx,qy,qz,qw" (m, quaternion): the truth is the object\'s pose composed with it. A learned model\'s frame is where the learner put it on the object (its `model_pose` in the learning cloud, composed with the inverse of the object\'s pose there), not the shipped model\'s [default: the identity]' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l ransac-trials -d 'RANSAC trials per hypothesis of the detector (`detect --trials`) [default: the detector\'s]' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l gripper -d 'The gripper\'s settings for --grasps: a TOML file of the [gripper] table\'s keys [default: a Robotiq 2F-85-class gripper]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l absent -d 'Remove the object from the scene and count false "found" answers'
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l json -d 'Print one JSON object instead of a table'
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -l grasps -d 'Plan a grasp for every correct detection and judge it against the truth: returned where a brute-force sampler over the true object and scene finds a valid one, and the first grasp valid (contacts within 3 mm of the true surface and in the friction cone, the gripper 3 mm clear of the true table and every other true object)'
complete -c sqscan -n "__fish_sqscan_using_subcommand eval" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l models-dir -d 'Directory of object models [default: $SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l labels -d 'Labels file (JSON: one entry a scene, its objects with class, identity, pose, support, centroid, visible, upright)' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l clouds -d 'Directory of the scenes\' clouds (SCENE.pcd for each labelled scene)' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l model -d 'Model name (looked up in the models directory) or model file' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l class -d 'The labelled class the model should find (e.g. mug, white_bowl)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l identity -d 'The labelled identity (one physical object) the model should find (e.g. biscuit_tin)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l catalogue -d 'The objects\' sizes by identity, a markdown table with LxWxH in mm (an answer is on an object within max(5 cm, half its largest size)) [default: CATALOGUE.md in the labels file\'s directory or its parent, where there is one]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l learned-from -d 'The view the model was learned from, SCENE:GROUP: answers there are neutral and it is not counted in recall' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l seed -d 'Seed of every random choice of the search' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l max-range -d 'Ignore points farther than this from the viewpoint (m)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l gripper -d 'The gripper\'s settings for --grasps: a TOML file of the [gripper] table\'s keys [default: a Robotiq 2F-85-class gripper]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l json -d 'Print one JSON object instead of the text report'
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l ignore-colour -d 'Do not check a found object\'s colours against the model\'s (where both have colours)'
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -l grasps -d 'Plan grasps for every right answer and check the first against the labels: how many found objects get a grasp, how many first grasps sweep no point that is not the object\'s, and of those without, how many have one that a brute-force sampler over the fit finds'
complete -c sqscan -n "__fish_sqscan_using_subcommand eval-real" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and not __fish_seen_subcommand_from ptu rig help" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and not __fish_seen_subcommand_from ptu rig help" -f -a "ptu" -d 'Run a mock pan-tilt unit on a pty until interrupted'
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and not __fish_seen_subcommand_from ptu rig help" -f -a "rig" -d 'Run the mock scanning rig until interrupted: a mock PTU on one pty and a mock profile sensor on another that sees the scene from the PTU\'s current angles'
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and not __fish_seen_subcommand_from ptu rig help" -f -a "help" -d 'Print this message or the help of the given subcommand(s)'
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from ptu" -l protocol -d 'The protocol the mock PTU speaks' -r -f -a "powercube\t'AMTEC/Schunk PowerCube modules over RS-232'
flir\t'FLIR / Directed Perception PTU-D46 (ASCII)'"
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from ptu" -l link -d 'Keep a symlink to the pty here (replaced if it is a symlink)' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from ptu" -l garbage-every -d 'Send 1-16 random bytes before every Nth reply' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from ptu" -l drop-every -d 'Drop every Nth reply' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from ptu" -l corrupt-every -d 'Send every Nth reply with a bad checksum' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from ptu" -l delay-ms -d 'Delay every reply by this many milliseconds' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from ptu" -l disconnect-after -d 'Close the pty (unplug) after N replies' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from ptu" -l replug-after-ms -d 'After an unplug, plug a fresh device in (new pty, same link) after this many milliseconds' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from ptu" -l seed -d 'Seed of the garbage bytes (and, for the rig, of the sensor noise)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from ptu" -s h -l help -d 'Print help (see more with \'--help\')'
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l models-dir -d 'Directory of object models [default: $SQSCAN_MODELS_DIR, else the first of ./models, /etc/sqscan/models, /usr/share/sqscan/models that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l scene -d 'Scene file whose table, objects and rig the sensor sees' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l protocol -d 'The protocol the mock PTU speaks' -r -f -a "powercube\t'AMTEC/Schunk PowerCube modules over RS-232'
flir\t'FLIR / Directed Perception PTU-D46 (ASCII)'"
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l ptu-link -d 'Keep a symlink to the PTU\'s pty here' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l sensor-link -d 'Keep a symlink to the sensor\'s pty here' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l rate -d 'Profiles a second while acquiring' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l sensor -d 'The sensor: an SQPF stream on a pty, or a GigE Vision line-profile camera (aravis\'s camera emulator; needs the gige feature) on --gige-address, alongside the idle SQPF pty' -r -f -a "sqpf\t''
gige\t''"
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l gige-address -d 'Interface address the GigE Vision camera serves on (run it in a private network namespace: see drivers/README.md)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l rows-per-frame -d 'Profiles a GigE Vision block (the camera\'s Height)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l camera-clock-offset -d 'The GigE Vision camera\'s clock reads this much ahead of the host\'s (s)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l camera-clock-drift -d '...and runs this much fast (ppm; negative: slow)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l camera-unplug-after -d 'Unplug the GigE Vision camera SECS after the rig starts (the emulator stops and closes its sockets)...' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l camera-replug-after -d '...and plug a fresh one in on the same address SECS later' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l ptu-replug-after -d 'After the PTU\'s --disconnect-after unplug, plug the same unit back in SECS later: a new pty, the --ptu-link symlink re-pointed at it, same angles; once (it is not unplugged again). The sensor keeps streaming meanwhile' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l tilt-sign -d 'How the unit\'s tilt is mounted: joint tilt = SIGN x device tilt. -1 for a PTU-D46, which tilts down at negative positions (use it with calibration/sim_rig_flir.toml)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l garbage-every -d 'Send 1-16 random bytes before every Nth reply' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l drop-every -d 'Drop every Nth reply' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l corrupt-every -d 'Send every Nth reply with a bad checksum' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l delay-ms -d 'Delay every reply by this many milliseconds' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l disconnect-after -d 'Close the pty (unplug) after N replies' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l replug-after-ms -d 'After an unplug, plug a fresh device in (new pty, same link) after this many milliseconds' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l seed -d 'Seed of the garbage bytes (and, for the rig, of the sensor noise)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l sensor-garbage-every -d 'Send 1-16 random bytes before every Nth frame' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l sensor-drop-every -d 'Drop every Nth frame (its sequence number is used up)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l sensor-corrupt-every -d 'Send every Nth frame with a bad CRC' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -l sensor-disconnect-after -d 'Close the sensor\'s pty (unplug) after N frames' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from rig" -s h -l help -d 'Print help (see more with \'--help\')'
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from help" -f -a "ptu" -d 'Run a mock pan-tilt unit on a pty until interrupted'
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from help" -f -a "rig" -d 'Run the mock scanning rig until interrupted: a mock PTU on one pty and a mock profile sensor on another that sees the scene from the PTU\'s current angles'
complete -c sqscan -n "__fish_sqscan_using_subcommand mock; and __fish_seen_subcommand_from help" -f -a "help" -d 'Print this message or the help of the given subcommand(s)'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l device -d 'Serial port (or a mock\'s pty link)' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l protocol -d 'The unit\'s protocol' -r -f -a "powercube\t'AMTEC/Schunk PowerCube modules over RS-232'
flir\t'FLIR / Directed Perception PTU-D46 (ASCII)'"
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l baud -d 'Line speed [default: 38400 for powercube, 9600 for flir]' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l pan-module -d 'PowerCube module id of the pan joint [default: 12]' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l tilt-module -d 'PowerCube module id of the tilt joint [default: 11]' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l pan-sign -d 'Pan axis sign (+1 or -1): joint = sign * device + offset' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l pan-offset -d 'Pan axis offset (rad): the joint angle at device angle 0' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l tilt-sign -d 'Tilt axis sign (+1 or -1): joint = sign * device + offset (-1 for a PTU-D46 tilting down at negative positions)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l tilt-offset -d 'Tilt axis offset (rad): the joint angle at device angle 0' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l timeout -d 'Give up on a move after this many seconds' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -l json -d 'Print one JSON object (both joints\' angles, state words and limits, and a sweep\'s samples summary) instead of lines of text'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -s h -l help -d 'Print help (see more with \'--help\')'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -f -a "status" -d 'Print both joints\' angles, state words and limits'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -f -a "home" -d 'Reset and home (PowerCube: wait for HOME_OK; PTU-D46: its recalibrating reset)'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -f -a "move" -d 'Move to an absolute pose (an axis not given stays where it is) and wait until reached'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -f -a "sweep" -d 'Tilt from one angle to another at a constant speed, sampling the position on the way'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and not __fish_seen_subcommand_from status home move sweep help" -f -a "help" -d 'Print this message or the help of the given subcommand(s)'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from status" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from home" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from move" -l pan -d 'Pan joint angle to reach (rad)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from move" -l tilt -d 'Tilt joint angle to reach (rad)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from move" -l speed -d 'Joint speed (rad/s)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from move" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from sweep" -l from -d 'Tilt joint angle to start from (rad); the unit moves there first' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from sweep" -l to -d 'Tilt joint angle to end at (rad)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from sweep" -l speed -d 'Tilt speed during the sweep (rad/s)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from sweep" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from help" -f -a "status" -d 'Print both joints\' angles, state words and limits'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from help" -f -a "home" -d 'Reset and home (PowerCube: wait for HOME_OK; PTU-D46: its recalibrating reset)'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from help" -f -a "move" -d 'Move to an absolute pose (an axis not given stays where it is) and wait until reached'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from help" -f -a "sweep" -d 'Tilt from one angle to another at a constant speed, sampling the position on the way'
complete -c sqscan -n "__fish_sqscan_using_subcommand ptu; and __fish_seen_subcommand_from help" -f -a "help" -d 'Print this message or the help of the given subcommand(s)'
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -l device -d 'Serial port (or a mock\'s pty link), tcp://HOST:PORT for a networked sensor, or gige://ADDRESS for a GigE Vision line-profile camera (a build with the gige feature)' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -l feature -d 'GigE Vision: set a GenICam feature before grabbing, NAME=VALUE (true/false, an integer, a number or an enumeration entry); repeat for more, set in the order given' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -l rows-per-frame -d 'GigE Vision: profiles a block (the camera\'s Height) [default: the camera\'s]' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -l fraction-bits -d 'GigE Vision: fixed-point fraction bits of the profiles (the calibration\'s)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -l baud -d 'Line speed' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -l timeout -d 'Give up when no profile arrives for this many seconds' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -l json -d 'Print one JSON object (grab) or one a camera (discover) instead of text'
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -f -a "grab" -d 'Start acquisition, receive N profiles, stop, and print statistics'
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -f -a "discover" -d 'List the GigE Vision cameras that answer a discovery broadcast on this host\'s networks (give --device gige://ANY; a build with the gige feature)'
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and not __fish_seen_subcommand_from grab discover help" -f -a "help" -d 'Print this message or the help of the given subcommand(s)'
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and __fish_seen_subcommand_from grab" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and __fish_seen_subcommand_from discover" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and __fish_seen_subcommand_from help" -f -a "grab" -d 'Start acquisition, receive N profiles, stop, and print statistics'
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and __fish_seen_subcommand_from help" -f -a "discover" -d 'List the GigE Vision cameras that answer a discovery broadcast on this host\'s networks (give --device gige://ANY; a build with the gige feature)'
complete -c sqscan -n "__fish_sqscan_using_subcommand sensor; and __fish_seen_subcommand_from help" -f -a "help" -d 'Print this message or the help of the given subcommand(s)'
complete -c sqscan -n "__fish_sqscan_using_subcommand find" -l max-age -d 'Accept a sweep up to this old (s); else wait for the next one' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand find" -l timeout -d 'Give up after this long (s)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand find" -l grasps -d 'Up to N grasps of the daemon\'s gripper for each found instance, best first' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand find" -l socket -d 'The daemon\'s socket, or tcp://HOST:PORT for a daemon listening on TCP ([server] tcp) [default: $SQSCAN_SOCKET, else $XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock: the first that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand find" -l all -d 'Every instance, not only the best'
complete -c sqscan -n "__fish_sqscan_using_subcommand find" -l json -d 'Print the daemon\'s JSON replies as they are, one a line'
complete -c sqscan -n "__fish_sqscan_using_subcommand find" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand scan" -l timeout -d 'Give up after this long (s)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand scan" -l socket -d 'The daemon\'s socket, or tcp://HOST:PORT for a daemon listening on TCP ([server] tcp) [default: $SQSCAN_SOCKET, else $XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock: the first that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand scan" -l json -d 'Print the daemon\'s JSON replies as they are, one a line'
complete -c sqscan -n "__fish_sqscan_using_subcommand scan" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand cloud" -l out -d 'Write the sweep\'s points here (a binary PCD file, organized, with the sensor\'s viewpoint)' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand cloud" -l max-age -d 'Accept a sweep up to this old (s); else wait for the next one' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand cloud" -l timeout -d 'Give up after this long (s)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand cloud" -l socket -d 'The daemon\'s socket, or tcp://HOST:PORT for a daemon listening on TCP ([server] tcp) [default: $SQSCAN_SOCKET, else $XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock: the first that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand cloud" -l json -d 'Print the daemon\'s JSON replies as they are, one a line'
complete -c sqscan -n "__fish_sqscan_using_subcommand cloud" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand watch" -l count -d 'Stop after this many detection messages (default: until interrupted)' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand watch" -l grasps -d 'Up to N grasps of the daemon\'s gripper for each found instance, best first' -r
complete -c sqscan -n "__fish_sqscan_using_subcommand watch" -l socket -d 'The daemon\'s socket, or tcp://HOST:PORT for a daemon listening on TCP ([server] tcp) [default: $SQSCAN_SOCKET, else $XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock: the first that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand watch" -l json -d 'Print the daemon\'s JSON replies as they are, one a line'
complete -c sqscan -n "__fish_sqscan_using_subcommand watch" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand status" -l socket -d 'The daemon\'s socket, or tcp://HOST:PORT for a daemon listening on TCP ([server] tcp) [default: $SQSCAN_SOCKET, else $XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock: the first that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand status" -l json -d 'Print the daemon\'s JSON replies as they are, one a line'
complete -c sqscan -n "__fish_sqscan_using_subcommand status" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand models" -l socket -d 'The daemon\'s socket, or tcp://HOST:PORT for a daemon listening on TCP ([server] tcp) [default: $SQSCAN_SOCKET, else $XDG_RUNTIME_DIR/sqscand.sock or ./sqscand.sock, else /run/sqscan/sqscand.sock: the first that exists]' -r -F
complete -c sqscan -n "__fish_sqscan_using_subcommand models" -l json -d 'Print the daemon\'s JSON replies as they are, one a line'
complete -c sqscan -n "__fish_sqscan_using_subcommand models" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand completions" -l daemon -d 'The script for sqscand instead of sqscan'
complete -c sqscan -n "__fish_sqscan_using_subcommand completions" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand man" -s h -l help -d 'Print help'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "simulate" -d 'Simulate one sweep of a scene: writes cloud.ply, cloud.pcd, range.png and truth.json'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "show-model" -d 'Sample a model\'s surface into a PLY file (one colour a part)'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "info" -d 'Print a point cloud file\'s point count, finite points, organization and bounding box'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "detect" -d 'Find an object in a point cloud file; prints one JSON object'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "learn" -d 'Learn a model by showing the object: recover its superquadric from one scan'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "eval" -d 'Measure detection rate, false "found" rate, time and pose error on simulated sweeps'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "eval-real" -d 'Measure the detector on real scans labelled by object class: recall, false answers, time'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "mock" -d 'Run mock devices on pseudo-terminals (use their paths like hardware)'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "ptu" -d 'Bring-up tool for a pan-tilt unit: status, home, move, sweep'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "sensor" -d 'Bring-up tool for a profile sensor: grab profiles and print their statistics'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "find" -d 'Ask the daemon where an object is (from a recent sweep, or the next one)'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "scan" -d 'Ask the daemon for a sweep now; prints it when complete'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "cloud" -d 'Fetch a recent sweep\'s points from the daemon into a PCD file'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "watch" -d 'Print every sweep\'s detections of the given objects until interrupted'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "status" -d 'The daemon\'s devices, last sweep, rates and faults'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "models" -d 'The objects the daemon knows'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "completions" -d 'Print a shell completion script for sqscan (or, with --daemon, sqscand)'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "man" -d 'Write the manual pages of sqscan (one a subcommand) and sqscand into a directory'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and not __fish_seen_subcommand_from simulate show-model info detect learn eval eval-real mock ptu sensor find scan cloud watch status models completions man help" -f -a "help" -d 'Print this message or the help of the given subcommand(s)'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and __fish_seen_subcommand_from mock" -f -a "ptu" -d 'Run a mock pan-tilt unit on a pty until interrupted'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and __fish_seen_subcommand_from mock" -f -a "rig" -d 'Run the mock scanning rig until interrupted: a mock PTU on one pty and a mock profile sensor on another that sees the scene from the PTU\'s current angles'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and __fish_seen_subcommand_from ptu" -f -a "status" -d 'Print both joints\' angles, state words and limits'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and __fish_seen_subcommand_from ptu" -f -a "home" -d 'Reset and home (PowerCube: wait for HOME_OK; PTU-D46: its recalibrating reset)'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and __fish_seen_subcommand_from ptu" -f -a "move" -d 'Move to an absolute pose (an axis not given stays where it is) and wait until reached'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and __fish_seen_subcommand_from ptu" -f -a "sweep" -d 'Tilt from one angle to another at a constant speed, sampling the position on the way'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and __fish_seen_subcommand_from sensor" -f -a "grab" -d 'Start acquisition, receive N profiles, stop, and print statistics'
complete -c sqscan -n "__fish_sqscan_using_subcommand help; and __fish_seen_subcommand_from sensor" -f -a "discover" -d 'List the GigE Vision cameras that answer a discovery broadcast on this host\'s networks (give --device gige://ANY; a build with the gige feature)'
