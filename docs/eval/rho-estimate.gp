# rho-estimate.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot rho-estimate.gp
if (!exists("outfile")) outfile = "rho-estimate.png"
set terminal pngcairo size 900,650 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
set title "B-RANSAC's rho_b estimated from the data (BSF pass) vs the true rho_b"
set xlabel "rho_b of the data"
set ylabel "estimated rho_b"
set grid
set key top left
set xrange [0:1]
set yrange [0:1]
set y2label "robustness"
set y2range [0:1.05]
set y2tics
plot x with lines dt 2 lc rgb "gray" title "ideal", "rho-estimate.csv" skip 1 using 1:2:3:4 with yerrorlines lw 2 title "estimate (mean, min..max over seeds)", "" skip 1 using 1:5 axes x1y2 with linespoints title "B-RANSAC robustness with it"
