difference() { cylinder(r=143.79, h=1.2, $fn=360); translate([0, 0, -1]) cylinder(r=131.79, h=5, $fn=360); }
