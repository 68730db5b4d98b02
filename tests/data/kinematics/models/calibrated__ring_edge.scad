difference() { cylinder(r=156.20, h=1.2, $fn=360); translate([0, 0, -1]) cylinder(r=146.70, h=5, $fn=360); }
